#pragma once
// Durable state of the service: trials with their stages, and uploaded models, in SQLite (WAL).
// One connection behind a mutex: the service is one process and SQLite serialises writers anyway.
// (The scale-out path keeps this interface over PostgreSQL.)
#include <sqlite3.h>

#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

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
  nlohmann::json to_json() const;
};

struct ModelRecord {
  std::string id, name, created_at;
  nlohmann::json warnings = nlohmann::json::array();
  nlohmann::json summary = nlohmann::json::object();
};

class Store {
 public:
  explicit Store(const std::string& path);  // creates the schema
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  void insert_trial(const TrialRecord& t);
  std::optional<TrialRecord> trial(const std::string& id);
  // Newest first; status empty = all.
  std::vector<TrialRecord> trials(const std::string& status, int limit, int offset);
  int count_trials(const std::string& status);
  // Takes the oldest queued trial and marks it running; nullopt when none.
  std::optional<TrialRecord> claim_next();
  void set_status(const std::string& id, const std::string& status, const nlohmann::json& error = nullptr);
  void set_stage(const std::string& id, const StageRecord& stage);
  bool delete_trial(const std::string& id);
  // Trials that were running when the process stopped go back to the queue; returns their ids.
  std::vector<std::string> requeue_interrupted();

  void insert_model(const ModelRecord& m);
  std::optional<ModelRecord> model(const std::string& id);
  std::vector<ModelRecord> models();

 private:
  sqlite3* db_ = nullptr;
  std::mutex mutex_;
  void exec(const char* sql);
  std::vector<TrialRecord> query_trials(const std::string& where, const std::vector<std::string>& args, int limit, int offset);
};

std::string now_iso8601();
std::string new_id();  // 16 random hex digits

}  // namespace cpgait::services
