#pragma once
// Durable state of the service: trials with their stages, uploaded models, and the leases by which
// workers hold running trials. One schema on SQLite (the embedded default, WAL) or PostgreSQL (many
// worker machines); the schema version is recorded and an older store is migrated when opened.
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sql_connection.h"

namespace cpgait::services {

struct StageRecord {
  std::string name;
  std::string state = "pending";  // pending | running | done | failed | skipped | cancelled
  double progress = 0;
  double seconds = 0;
  nlohmann::json summary = nlohmann::json::object();
};

struct TrialRecord {
  std::string id;
  std::string name;
  std::string status;  // queued | running | done | failed | cancelled
  std::string created_at, updated_at;
  nlohmann::json options;
  nlohmann::json error;  // {"code","message","field","line"} when failed
  std::vector<StageRecord> stages;
  std::string worker;  // the lease holder while running
  int attempt = 0;     // claims so far; a running trial's work folder is work-<attempt>
  nlohmann::json to_json() const;
};

struct ModelRecord {
  std::string id, name, created_at;
  nlohmann::json warnings = nlohmann::json::array();
  nlohmann::json summary = nlohmann::json::object();
};

// What /metrics reports, read from the store so that it covers every worker process.
struct StoreMetrics {
  std::map<std::string, long> trials_by_status;
  std::map<std::string, long> running_by_worker;
  long lease_expiries = 0;
  std::map<std::string, std::pair<double, long>> stage_seconds;  // stage -> (sum, count) over done stages
};

class Store {
 public:
  static constexpr int kSchemaVersion = 2;
  // spec: "sqlite:PATH", a plain path (SQLite), or a PostgreSQL URI ("postgresql://user@host:port/db").
  // Opens (creating or migrating the schema); PostgreSQL keeps up to `connections` sessions.
  explicit Store(const std::string& spec, int connections = 4);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  SqlDialect dialect() const { return dialect_; }
  int schema_version();

  void insert_trial(const TrialRecord& t);
  std::optional<TrialRecord> trial(const std::string& id);
  // Newest first; status empty = all.
  std::vector<TrialRecord> trials(const std::string& status, int limit, int offset);
  int count_trials(const std::string& status);
  bool delete_trial(const std::string& id);

  // --- leases: a worker holds a running trial until lease_s after its last renewal ---
  // Takes the oldest queued trial (SKIP LOCKED on PostgreSQL); nullopt when none is queued.
  std::optional<TrialRecord> claim_next(const std::string& worker, double lease_s);
  enum class Lease { kHeld, kCancelRequested, kLost };
  // kLost: the trial was deleted, or its lease expired and someone re-queued it.
  Lease renew_lease(const std::string& id, const std::string& worker, int attempt, double lease_s);
  // A stage's state, written only while `attempt` holds the trial.
  void set_stage(const std::string& id, int attempt, const StageRecord& stage);
  // Ends the attempt in one transaction: checks the lease is still held, calls publish() (which moves
  // the results into place), records the status, error and result checksums, and marks stages left
  // running or pending with the trial's fate. Returns false, without calling publish, if the lease
  // was lost; a throwing publish rolls everything back.
  bool finish_trial(const std::string& id, const std::string& worker, int attempt, const std::string& status,
                    const nlohmann::json& error, const nlohmann::json& checksums, const std::function<void()>& publish);
  // A worker shutting down hands its trial back to the queue (if it still holds it).
  void release_trial(const std::string& id, const std::string& worker, int attempt);
  // Running trials whose lease ran out go back to the queue (or to cancelled, if that was asked);
  // counted as lease expiries. Returns their ids.
  std::vector<std::string> requeue_expired();
  // The embedded store's restart: every running trial goes back to the queue (its one process died).
  std::vector<std::string> requeue_running();
  enum class Cancel { kCancelled, kCancelling, kFinished };
  // Queued: cancelled at once. Running: flagged; its worker sees the flag at its next renewal.
  Cancel request_cancel(const std::string& id);

  StoreMetrics metrics();

  void insert_model(const ModelRecord& m);
  std::optional<ModelRecord> model(const std::string& id);
  std::vector<ModelRecord> models();

 private:
  SqlDialect dialect_;
  std::function<std::unique_ptr<SqlConnection>()> connect_;
  int max_connections_;
  int open_connections_ = 0;
  std::vector<std::unique_ptr<SqlConnection>> idle_;
  std::mutex pool_mutex_;
  std::condition_variable pool_free_;

  std::string sql(const std::string& text) const;  // dialect tokens: {now_ms} {real} {skip_locked} {for_update}
  // Runs f on a pooled connection, inside BEGIN/COMMIT when `transaction`; retried on a fresh
  // connection after transient errors (a restarted server) for up to 30 s.
  void with_connection(bool transaction, const std::function<void(SqlConnection&)>& f);
  void migrate();
  std::vector<TrialRecord> query_trials(SqlConnection& c, const std::string& where, const std::vector<SqlValue>& args, int limit, int offset);
};

std::string now_iso8601();
std::string new_id();  // 16 random hex digits

}  // namespace cpgait::services
