#include "jobs.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "output_files.h"
#include "pipeline.h"
#include "sha256.h"

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

void ChangeSignal::notify() {
  {
    std::lock_guard lock(mutex_);
    ++version_;
  }
  changed_.notify_all();
}

std::uint64_t ChangeSignal::wait(std::uint64_t seen, int timeout_ms) {
  std::unique_lock lock(mutex_);
  changed_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return version_ > seen; });
  return version_;
}

std::uint64_t ChangeSignal::version() {
  std::lock_guard lock(mutex_);
  return version_;
}

namespace {

std::string default_worker_name() {
  char host[256] = "host";
  gethostname(host, sizeof host - 1);
  return std::string(host) + ":" + std::to_string(getpid()) + ":" + new_id().substr(0, 6);
}

}  // namespace

JobRunner::JobRunner(Store& store, ChangeSignal& changes, std::string data_dir, RunnerOptions options)
    : store_(store), changes_(changes), data_dir_(std::move(data_dir)), options_(std::move(options)) {
  if (options_.name.empty()) options_.name = default_worker_name();
}

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
  if (options_.requeue_running_on_start)
    for (const auto& id : store_.requeue_running())
      log_line({{"event", "requeued"}, {"trial", id}, {"why", "interrupted by a restart"}});
  for (int i = 0; i < options_.threads; ++i) threads_.emplace_back([this] { worker(); });
  heartbeat_ = std::thread([this] { heartbeat(); });
}

void JobRunner::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    for (auto& [id, h] : held_) h.stop = true;  // running trials stop at their next check and go back to the queue
  }
  work_.notify_all();
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  threads_.clear();
  if (heartbeat_.joinable()) heartbeat_.join();
}

void JobRunner::wake() { work_.notify_one(); }

bool JobRunner::cancel(const std::string& id) {
  const Store::Cancel c = store_.request_cancel(id);
  if (c == Store::Cancel::kFinished) return false;
  {
    std::lock_guard lock(mutex_);
    if (auto it = held_.find(id); it != held_.end()) it->second.stop = true;  // ours: no need to wait for the heartbeat
  }
  changes_.notify();
  return true;
}

bool JobRunner::stop_requested(const std::string& id) {
  std::lock_guard lock(mutex_);
  const auto it = held_.find(id);
  return it == held_.end() || it->second.stop;
}

void JobRunner::heartbeat() {
  bool store_down = false;
  while (true) {
    {
      std::unique_lock lock(mutex_);
      work_.wait_for(lock, std::chrono::duration<double>(options_.heartbeat_s), [&] { return stopping_; });
      if (stopping_) return;
    }
    try {
      std::map<std::string, Held> held;
      {
        std::lock_guard lock(mutex_);
        held = held_;
      }
      for (const auto& [id, h] : held) {
        const Store::Lease lease = store_.renew_lease(id, options_.name, h.attempt, options_.lease_s);
        if (lease == Store::Lease::kHeld) continue;
        std::lock_guard lock(mutex_);
        if (auto it = held_.find(id); it != held_.end()) it->second.stop = true;
        if (lease == Store::Lease::kLost) log_line({{"event", "lease_lost"}, {"trial", id}, {"worker", options_.name}});
      }
      // Trials whose worker died: back to the queue for whoever is free.
      const auto requeued = store_.requeue_expired();
      for (const auto& id : requeued) log_line({{"event", "requeued"}, {"trial", id}, {"why", "its lease expired"}});
      if (!requeued.empty()) work_.notify_all(), changes_.notify();
      if (store_down) log_line({{"event", "store_reconnected"}, {"worker", options_.name}});
      store_down = false;
    } catch (const std::exception& e) {
      if (!store_down) log_line({{"event", "store_unavailable"}, {"worker", options_.name}, {"error", e.what()}});
      store_down = true;
    }
  }
}

void JobRunner::worker() {
  while (true) {
    {
      std::unique_lock lock(mutex_);
      work_.wait_for(lock, std::chrono::milliseconds(500), [&] { return stopping_; });
      if (stopping_) return;
    }
    // Drain the queue before sleeping again.
    try {
      while (std::optional<TrialRecord> t = store_.claim_next(options_.name, options_.lease_s)) {
        running_++;
        run_trial(*t);
        running_--;
        std::lock_guard lock(mutex_);
        if (stopping_) return;
      }
    } catch (const std::exception& e) {  // the store is unreachable: try again after the wait
      log_line({{"event", "store_unavailable"}, {"worker", options_.name}, {"error", e.what()}});
    }
  }
}

namespace {

class StoreObserver : public PipelineObserver {
 public:
  StoreObserver(Store& store, ChangeSignal& changes, const TrialRecord& t, std::function<bool()> cancelled)
      : store_(store), changes_(changes), trial_(t), cancelled_(std::move(cancelled)) {}
  void stage_started(const std::string& stage) override { update(stage, "running", 0, 0, json::object()); }
  void stage_progress(const std::string& stage, double fraction) override {
    // Progress reaches the store ten times a second at most: other processes poll it.
    const auto now = std::chrono::steady_clock::now();
    if (now - last_progress_ < std::chrono::milliseconds(100)) return;
    last_progress_ = now;
    update(stage, "running", fraction, 0, json::object());
  }
  void stage_finished(const std::string& stage, double seconds, const json& summary) override {
    update(stage, "done", 1, seconds, summary);
    log_line({{"event", "stage"}, {"trial", trial_.id}, {"stage", stage}, {"state", "done"}, {"seconds", seconds}});
  }
  bool cancelled() const override { return cancelled_(); }

 private:
  Store& store_;
  ChangeSignal& changes_;
  const TrialRecord& trial_;
  std::function<bool()> cancelled_;
  std::chrono::steady_clock::time_point last_progress_{};
  void update(const std::string& stage, const std::string& state, double progress, double seconds, const json& summary) {
    store_.set_stage(trial_.id, trial_.attempt, {stage, state, progress, seconds, summary});
    changes_.notify();
  }
};

// Every result file's SHA-256, by name.
json result_checksums(const fs::path& dir) {
  json sums = json::object();
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file()) sums[e.path().filename().string()] = sha256_hex(text::read_file(e.path().string()));
  return sums;
}

json error_json(const std::string& code, const std::string& message, const std::string& field = "", int line = 0) {
  json e = {{"code", code}, {"message", message}};
  if (!field.empty()) e["field"] = field;
  if (line > 0) e["line"] = line;
  return e;
}

}  // namespace

void JobRunner::run_trial(const TrialRecord& t) {
  const auto start = std::chrono::steady_clock::now();
  const fs::path dir = trial_dir(t.id), work = dir / ("work-" + std::to_string(t.attempt)), results = dir / "results";
  {
    std::lock_guard lock(mutex_);
    held_[t.id] = {t.attempt, false};
  }
  changes_.notify();
  log_line({{"event", "trial"}, {"trial", t.id}, {"state", "running"}, {"worker", options_.name}, {"attempt", t.attempt}});
  std::string status = "done";
  json error = nullptr, checksums = nullptr;
  std::error_code ec;
  // Earlier attempts' folders (their workers died or lost the lease): they never publish.
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().filename().string().rfind("work", 0) == 0 && e.path() != work) fs::remove_all(e.path(), ec);
  try {
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
    StoreObserver observer(store_, changes_, t, [this, &t] { return stop_requested(t.id); });
    run_pipeline(in, options, work.string(), &observer);
    checksums = result_checksums(work);
  } catch (const InputError& e) {
    status = "failed";
    error = error_json("invalid_input", e.what(), e.field(), e.line());
  } catch (const std::exception& e) {
    status = stop_requested(t.id) ? "cancelled" : "failed";
    if (status == "failed") error = error_json("stage_failed", e.what());
  }
  // The results appear at once, and only if this attempt still holds the trial. Idempotent, as a
  // transaction retried after a dropped connection calls it again.
  auto publish = [&] {
    if (status != "done" || !fs::exists(work)) return;
    fs::remove_all(results);  // an earlier attempt's, moved but never committed
    fs::rename(work, results);
  };
  bool held = false;
  bool shutting_down = false;
  {
    std::lock_guard lock(mutex_);
    shutting_down = stopping_ && status != "done";
  }
  try {
    if (shutting_down) {
      store_.release_trial(t.id, options_.name, t.attempt);  // cancelled trials are not released: they end below
      held = store_.trial(t.id).value_or(TrialRecord{}).status == "running";
      if (held) held = store_.finish_trial(t.id, options_.name, t.attempt, "cancelled", nullptr, nullptr, publish);
      status = held ? "cancelled" : "released";
    } else {
      held = store_.finish_trial(t.id, options_.name, t.attempt, status, error, checksums, publish);
    }
  } catch (const std::exception& e) {
    log_line({{"event", "finish_failed"}, {"trial", t.id}, {"error", e.what()}});
  }
  fs::remove_all(work, ec);
  try {
    if (!held && !store_.trial(t.id)) fs::remove_all(dir, ec);  // deleted while it ran
  } catch (const std::exception&) {  // the store is down: the lease runs out and the trial re-runs
  }
  {
    std::lock_guard lock(mutex_);
    held_.erase(t.id);
  }
  changes_.notify();
  log_line({{"event", "trial"}, {"trial", t.id}, {"state", held || status == "released" ? status : "abandoned"}, {"worker", options_.name},
            {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()}});
}

}  // namespace cpgait::services
