#pragma once
// Runs queued trials on a bounded pool of threads, as `cpgait serve` (embedded) or `cpgait worker`
// (one of many processes on a shared PostgreSQL store and data folder). A claimed trial is held by a
// lease that a heartbeat renews; a trial whose holder died is re-queued when its lease runs out.
// Results are built in <trial>/work-<attempt> and renamed to <trial>/results in the transaction
// that marks the trial done, so a crash never leaves a half-written result where a finished one is
// expected, and a worker that lost its lease never publishes.
#include <atomic>
#include <condition_variable>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "store.h"

namespace cpgait::services {

// Wakes this process' waiters (event streams, idle workers) when a trial changed here; other
// processes' changes are seen by polling the store.
class ChangeSignal {
 public:
  void notify();
  // Waits until the version passes `seen` or timeout_ms pass; returns the version.
  std::uint64_t wait(std::uint64_t seen, int timeout_ms);
  std::uint64_t version();

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::uint64_t version_ = 0;
};

struct RunnerOptions {
  int threads = 2;           // trials run at once by this process; 0: none (an API-only server)
  double lease_s = 10;       // s a running trial stays held after its worker's last heartbeat
  double heartbeat_s = 1;    // s between lease renewals, cancel checks and expired-lease sweeps
  bool requeue_running_on_start = false;  // embedded store: every running trial was this process'
  std::string name;          // worker name in the store; default host:pid:random
};

class JobRunner {
 public:
  JobRunner(Store& store, ChangeSignal& changes, std::string data_dir, RunnerOptions options);
  ~JobRunner();
  void start();
  void stop();
  void wake();  // a trial was queued
  // Queued: cancelled at once. Running (here or in another process): asked to stop at its next
  // heartbeat. Returns false if the trial is already finished.
  bool cancel(const std::string& id);
  std::string trial_dir(const std::string& id) const;
  std::string model_path(const std::string& model_id) const;
  std::string marker_set_path(const std::string& model_id) const;  // empty when the model has none
  const std::string& name() const { return options_.name; }
  int running() const { return running_.load(); }

 private:
  struct Held {
    int attempt = 0;
    bool stop = false;  // cancel asked, or the lease lost
  };
  Store& store_;
  ChangeSignal& changes_;
  std::string data_dir_;
  RunnerOptions options_;
  std::vector<std::thread> threads_;
  std::thread heartbeat_;
  std::mutex mutex_;
  std::condition_variable work_;
  bool stopping_ = false;
  std::map<std::string, Held> held_;  // trials running in this process
  std::atomic<int> running_{0};
  void worker();
  void heartbeat();
  void run_trial(const TrialRecord& t);
  bool stop_requested(const std::string& id);
};

// One JSON log line on stdout (requests, stages, service events).
void log_line(const nlohmann::json& fields);

}  // namespace cpgait::services
