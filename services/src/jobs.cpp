#include "jobs.h"

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "pipeline.h"
#include "output_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;
using nlohmann::json;

void log_line(const json& fields) {
  json j = fields;
  j["ts"] = now_iso8601();
  static std::mutex m;
  std::lock_guard lock(m);
  std::printf("%s\n", json_text(j).c_str());
  std::fflush(stdout);
}

void EventHub::publish(const std::string& trial, json event) {
  {
    std::lock_guard lock(mutex_);
    Stream& s = streams_[trial];
    s.events.emplace_back(s.next++, std::move(event));
    while (s.events.size() > 500) s.events.pop_front();
  }
  changed_.notify_all();
}

std::vector<std::pair<long, json>> EventHub::wait(const std::string& trial, long after, int timeout_ms) {
  std::unique_lock lock(mutex_);
  auto ready = [&] { return streams_.count(trial) && streams_[trial].next - 1 > after; };
  changed_.wait_for(lock, std::chrono::milliseconds(timeout_ms), ready);
  std::vector<std::pair<long, json>> out;
  if (!streams_.count(trial)) return out;
  for (const auto& e : streams_[trial].events)
    if (e.first > after) out.push_back(e);
  return out;
}

void EventHub::forget(const std::string& trial) {
  std::lock_guard lock(mutex_);
  streams_.erase(trial);
}

JobRunner::JobRunner(Store& store, EventHub& events, Metrics& metrics, std::string data_dir, int workers)
    : store_(store), events_(events), metrics_(metrics), data_dir_(std::move(data_dir)), workers_(std::max(1, workers)) {}

JobRunner::~JobRunner() { stop(); }

std::string JobRunner::trial_dir(const std::string& id) const { return (fs::path(data_dir_) / "trials" / id).string(); }
std::string JobRunner::model_path(const std::string& model_id) const {
  return (fs::path(data_dir_) / "models" / model_id / "model.osim").string();
}

std::string JobRunner::marker_set_path(const std::string& model_id) const {
  const fs::path p = fs::path(data_dir_) / "models" / model_id / "markerset.xml";
  return fs::exists(p) ? p.string() : std::string();
}

void JobRunner::start() {
  for (const auto& id : store_.requeue_interrupted()) {
    std::error_code ec;
    fs::remove_all(fs::path(trial_dir(id)) / "work", ec);
    log_line({{"event", "requeued"}, {"trial", id}, {"why", "interrupted by a restart"}});
  }
  for (int i = 0; i < workers_; ++i) threads_.emplace_back([this] { worker(); });
}

void JobRunner::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  work_.notify_all();
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  threads_.clear();
}

void JobRunner::wake() { work_.notify_one(); }

bool JobRunner::cancel(const std::string& id) {
  const auto t = store_.trial(id);
  if (!t || (t->status != "queued" && t->status != "running")) return false;
  {
    std::lock_guard lock(mutex_);
    cancel_requests_.insert(id);
  }
  if (t->status == "queued") {
    store_.set_status(id, "cancelled");
    events_.publish(id, {{"status", "cancelled"}});
  }
  return true;
}

bool JobRunner::cancel_requested(const std::string& id) {
  std::lock_guard lock(mutex_);
  return cancel_requests_.count(id) > 0;
}

void JobRunner::worker() {
  while (true) {
    std::optional<TrialRecord> t;
    {
      std::unique_lock lock(mutex_);
      work_.wait_for(lock, std::chrono::milliseconds(500), [&] { return stopping_; });
      if (stopping_) return;
    }
    // Drain the queue before sleeping again.
    while ((t = store_.claim_next())) {
      if (cancel_requested(t->id)) {
        store_.set_status(t->id, "cancelled");
        continue;
      }
      running_++;
      run_trial(*t);
      running_--;
      std::lock_guard lock(mutex_);
      if (stopping_) return;
    }
  }
}

namespace {

class StoreObserver : public PipelineObserver {
 public:
  StoreObserver(Store& store, EventHub& events, Metrics& metrics, const TrialRecord& t, std::function<bool()> cancelled)
      : store_(store), events_(events), metrics_(metrics), trial_(t), cancelled_(std::move(cancelled)) {}
  void stage_started(const std::string& stage) override { update(stage, "running", 0, 0, json::object()); }
  void stage_progress(const std::string& stage, double fraction) override { update(stage, "running", fraction, 0, json::object()); }
  void stage_finished(const std::string& stage, double seconds, const json& summary) override {
    update(stage, "done", 1, seconds, summary);
    {
      std::lock_guard lock(metrics_.mutex);
      auto& m = metrics_.stage_seconds[stage];
      m.first += seconds;
      m.second += 1;
    }
    log_line({{"event", "stage"}, {"trial", trial_.id}, {"stage", stage}, {"state", "done"}, {"seconds", seconds}});
  }
  bool cancelled() const override { return cancelled_(); }

 private:
  Store& store_;
  EventHub& events_;
  Metrics& metrics_;
  const TrialRecord& trial_;
  std::function<bool()> cancelled_;
  void update(const std::string& stage, const std::string& state, double progress, double seconds, const json& summary) {
    store_.set_stage(trial_.id, {stage, state, progress, seconds, summary});
    events_.publish(trial_.id, {{"status", "running"}, {"stage", stage}, {"state", state}, {"progress", progress}});
  }
};

json error_json(const std::string& code, const std::string& message, const std::string& field = "", int line = 0) {
  json e = {{"code", code}, {"message", message}};
  if (!field.empty()) e["field"] = field;
  if (line > 0) e["line"] = line;
  return e;
}

}  // namespace

void JobRunner::run_trial(const TrialRecord& t) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path dir = trial_dir(t.id), work = dir / "work", results = dir / "results";
  events_.publish(t.id, {{"status", "running"}});
  log_line({{"event", "trial"}, {"trial", t.id}, {"state", "running"}});
  std::string status = "done";
  json error = nullptr;
  try {
    std::error_code ec;
    fs::remove_all(work, ec);
    const PipelineOptions options = PipelineOptions::from_json(t.options, "options");
    TrialInputs in;
    in.name = t.name;
    in.model_path = model_path(options.model_id);
    if (!options.scale_muscles_from_id.empty()) in.generic_model_path = model_path(options.scale_muscles_from_id);
    in.marker_set_path = marker_set_path(options.model_id);
    load_footage_inputs((dir / "inputs").string(), in);
    if (!in.has_footage()) {
      in.markers = text::read_file((dir / "inputs" / "markers.trc").string());
      in.markers_name = "markers.trc";
    }
    if (fs::exists(dir / "inputs" / "grf.mot")) {
      in.grf = text::read_file((dir / "inputs" / "grf.mot").string());
      in.grf_name = "grf.mot";
      in.loads = text::read_file((dir / "inputs" / "loads.xml").string());
      in.loads_name = "loads.xml";
    }
    if (fs::exists(dir / "inputs" / "static.trc")) {
      in.static_markers = text::read_file((dir / "inputs" / "static.trc").string());
      in.static_name = "static.trc";
    }
    if (fs::exists(dir / "inputs" / "scale_setup.xml")) {
      in.scale_setup = text::read_file((dir / "inputs" / "scale_setup.xml").string());
      in.scale_setup_name = "scale_setup.xml";
    }
    for (const CmcFilePart& f : kCmcFileParts)
      if (const fs::path p = dir / "inputs" / (std::string(f.part) + ".xml"); fs::exists(p)) {
        in.*f.content = text::read_file(p.string());
        in.*f.name = p.filename().string();
      }
    StoreObserver observer(store_, events_, metrics_, t, [this, &t] { return cancel_requested(t.id); });
    run_pipeline(in, options, work.string(), &observer);
    fs::remove_all(results, ec);
    fs::rename(work, results);  // the finished results appear at once
  } catch (const InputError& e) {
    status = "failed";
    error = error_json("invalid_input", e.what(), e.field(), e.line());
  } catch (const std::exception& e) {
    status = cancel_requested(t.id) ? "cancelled" : "failed";
    if (status == "failed") error = error_json("stage_failed", e.what());
  }
  if (status != "done") {
    std::error_code ec;
    fs::remove_all(work, ec);
    // Stages left running or pending are marked with the trial's fate.
    if (const auto now = store_.trial(t.id))
      for (auto s : now->stages)
        if (s.state == "running" || s.state == "pending") {
          s.state = status == "cancelled" ? "cancelled" : (s.state == "running" ? "failed" : "skipped");
          store_.set_stage(t.id, s);
        }
  }
  store_.set_status(t.id, status, error);
  {
    std::lock_guard lock(mutex_);
    cancel_requests_.erase(t.id);
  }
  json done = {{"status", status}};
  if (!error.is_null()) done["error"] = error;
  events_.publish(t.id, done);
  log_line({{"event", "trial"}, {"trial", t.id}, {"state", status},
            {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()}});
}

}  // namespace cpgait::services
