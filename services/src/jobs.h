#pragma once
// Runs queued trials on a bounded pool of worker threads and publishes their progress.
// Results are built in <trial>/work and renamed to <trial>/results when every stage is done, so a
// crash never leaves a half-written result where a finished one is expected; a restart puts
// interrupted trials back in the queue.
#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "store.h"

namespace cpgait::services {

// Progress events per trial, numbered, for Server-Sent Events.
class EventHub {
 public:
  void publish(const std::string& trial, nlohmann::json event);
  // Events after `after` (sequence numbers start at 1); waits up to timeout_ms for one.
  std::vector<std::pair<long, nlohmann::json>> wait(const std::string& trial, long after, int timeout_ms);
  void forget(const std::string& trial);

 private:
  struct Stream {
    long next = 1;
    std::deque<std::pair<long, nlohmann::json>> events;  // the last few hundred
  };
  std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::string, Stream> streams_;
};

struct Metrics {
  std::mutex mutex;
  std::map<std::string, std::pair<double, long>> stage_seconds;  // stage -> (sum, count)
  long requests = 0;
};

class JobRunner {
 public:
  JobRunner(Store& store, EventHub& events, Metrics& metrics, std::string data_dir, int workers);
  ~JobRunner();
  void start();
  void stop();
  void wake();  // a trial was queued
  // Queued: cancelled at once. Running: asked to stop at the next check. Returns false if the trial
  // is already finished.
  bool cancel(const std::string& id);
  std::string trial_dir(const std::string& id) const;
  std::string model_path(const std::string& model_id) const;
  std::string marker_set_path(const std::string& model_id) const;  // empty when the model has none
  int running() const { return running_.load(); }

 private:
  Store& store_;
  EventHub& events_;
  Metrics& metrics_;
  std::string data_dir_;
  int workers_;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable work_;
  bool stopping_ = false;
  std::set<std::string> cancel_requests_;
  std::atomic<int> running_{0};
  void worker();
  void run_trial(const TrialRecord& t);
  bool cancel_requested(const std::string& id);
};

// One JSON log line on stdout (requests, stages, service events).
void log_line(const nlohmann::json& fields);

}  // namespace cpgait::services
