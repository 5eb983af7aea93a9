#include "store.h"

#include <chrono>
#include <ctime>
#include <random>
#include <stdexcept>

#include "output_files.h"

namespace cpgait::services {
using nlohmann::json;

namespace {

// A prepared statement that finalizes itself; binds strings by position.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &s_, nullptr) != SQLITE_OK)
      throw std::runtime_error(std::string("sqlite prepare: ") + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(s_); }
  Statement& bind(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Statement& bind(int i, double v) {
    sqlite3_bind_double(s_, i, v);
    return *this;
  }
  Statement& bind(int i, int v) {
    sqlite3_bind_int(s_, i, v);
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(s_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw std::runtime_error(std::string("sqlite step: ") + sqlite3_errmsg(db_));
  }
  std::string text(int col) const {
    const auto* p = sqlite3_column_text(s_, col);
    return p ? reinterpret_cast<const char*>(p) : "";
  }
  double real(int col) const { return sqlite3_column_double(s_, col); }
  int integer(int col) const { return sqlite3_column_int(s_, col); }

 private:
  sqlite3* db_;
  sqlite3_stmt* s_ = nullptr;
};

json parse_or(const std::string& s, json fallback) {
  if (s.empty()) return fallback;
  return json::parse(s, nullptr, false).is_discarded() ? fallback : json::parse(s);
}

}  // namespace

std::string now_iso8601() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday, tm.tm_hour,
                tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buf;
}

std::string new_id() {
  static thread_local std::mt19937_64 rng(std::random_device{}() ^
                                          static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()));
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

json TrialRecord::to_json() const {
  json stages_json = json::array();
  for (const auto& s : stages)
    stages_json.push_back({{"name", s.name}, {"state", s.state}, {"progress", s.progress}, {"seconds", s.seconds}, {"summary", s.summary}});
  json j = {{"id", id}, {"name", name}, {"status", status}, {"created_at", created_at}, {"updated_at", updated_at},
            {"options", options}, {"stages", stages_json}};
  if (!error.is_null()) j["error"] = error;
  return j;
}

Store::Store(const std::string& path) {
  if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK)
    throw std::runtime_error(path + ": cannot open database: " + (db_ ? sqlite3_errmsg(db_) : "out of memory"));
  sqlite3_busy_timeout(db_, 5000);
  exec("PRAGMA journal_mode=WAL");
  exec("PRAGMA synchronous=NORMAL");
  exec("CREATE TABLE IF NOT EXISTS trials (id TEXT PRIMARY KEY, name TEXT, status TEXT NOT NULL, created_at TEXT, "
       "updated_at TEXT, options TEXT, error TEXT)");
  exec("CREATE INDEX IF NOT EXISTS trials_status ON trials(status, created_at)");
  exec("CREATE TABLE IF NOT EXISTS stages (trial_id TEXT NOT NULL, position INTEGER, name TEXT NOT NULL, state TEXT, "
       "progress REAL, seconds REAL, summary TEXT, PRIMARY KEY (trial_id, name))");
  exec("CREATE TABLE IF NOT EXISTS models (id TEXT PRIMARY KEY, name TEXT, created_at TEXT, warnings TEXT, summary TEXT)");
}

Store::~Store() { sqlite3_close(db_); }

void Store::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string msg = err ? err : "unknown";
    sqlite3_free(err);
    throw std::runtime_error(std::string("sqlite: ") + msg + " in: " + sql);
  }
}

void Store::insert_trial(const TrialRecord& t) {
  std::lock_guard lock(mutex_);
  exec("BEGIN");
  try {
    Statement(db_, "INSERT INTO trials (id, name, status, created_at, updated_at, options, error) VALUES (?,?,?,?,?,?,?)")
        .bind(1, t.id).bind(2, t.name).bind(3, t.status).bind(4, t.created_at).bind(5, t.updated_at)
        .bind(6, json_text(t.options)).bind(7, t.error.is_null() ? std::string() : json_text(t.error)).step();
    int position = 0;
    for (const auto& s : t.stages)
      Statement(db_, "INSERT INTO stages (trial_id, position, name, state, progress, seconds, summary) VALUES (?,?,?,?,?,?,?)")
          .bind(1, t.id).bind(2, position++).bind(3, s.name).bind(4, s.state).bind(5, s.progress).bind(6, s.seconds)
          .bind(7, json_text(s.summary)).step();
    exec("COMMIT");
  } catch (...) {
    exec("ROLLBACK");
    throw;
  }
}

std::vector<TrialRecord> Store::query_trials(const std::string& where, const std::vector<std::string>& args, int limit, int offset) {
  const std::string sql = "SELECT id, name, status, created_at, updated_at, options, error FROM trials " + where +
                          " ORDER BY created_at DESC, id LIMIT ? OFFSET ?";
  Statement q(db_, sql.c_str());
  int i = 1;
  for (const auto& a : args) q.bind(i++, a);
  q.bind(i, limit);
  q.bind(i + 1, offset);
  std::vector<TrialRecord> out;
  while (q.step()) {
    TrialRecord t;
    t.id = q.text(0);
    t.name = q.text(1);
    t.status = q.text(2);
    t.created_at = q.text(3);
    t.updated_at = q.text(4);
    t.options = parse_or(q.text(5), json::object());
    t.error = parse_or(q.text(6), nullptr);
    out.push_back(std::move(t));
  }
  for (auto& t : out) {
    Statement s(db_, "SELECT name, state, progress, seconds, summary FROM stages WHERE trial_id = ? ORDER BY position");
    s.bind(1, t.id);
    while (s.step()) t.stages.push_back({s.text(0), s.text(1), s.real(2), s.real(3), parse_or(s.text(4), json::object())});
  }
  return out;
}

std::optional<TrialRecord> Store::trial(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto v = query_trials("WHERE id = ?", {id}, 1, 0);
  if (v.empty()) return std::nullopt;
  return v.front();
}

std::vector<TrialRecord> Store::trials(const std::string& status, int limit, int offset) {
  std::lock_guard lock(mutex_);
  return status.empty() ? query_trials("", {}, limit, offset) : query_trials("WHERE status = ?", {status}, limit, offset);
}

int Store::count_trials(const std::string& status) {
  std::lock_guard lock(mutex_);
  Statement q(db_, status.empty() ? "SELECT COUNT(*) FROM trials" : "SELECT COUNT(*) FROM trials WHERE status = ?");
  if (!status.empty()) q.bind(1, status);
  q.step();
  return q.integer(0);
}

std::optional<TrialRecord> Store::claim_next() {
  std::string id;
  {
    std::lock_guard lock(mutex_);
    Statement q(db_,
                "UPDATE trials SET status = 'running', updated_at = ? WHERE id = (SELECT id FROM trials WHERE status = "
                "'queued' ORDER BY created_at, id LIMIT 1) RETURNING id");
    q.bind(1, now_iso8601());
    if (!q.step()) return std::nullopt;
    id = q.text(0);
    while (q.step()) {
    }
  }
  return trial(id);
}

void Store::set_status(const std::string& id, const std::string& status, const json& error) {
  std::lock_guard lock(mutex_);
  Statement(db_, "UPDATE trials SET status = ?, updated_at = ?, error = ? WHERE id = ?")
      .bind(1, status).bind(2, now_iso8601()).bind(3, error.is_null() ? std::string() : json_text(error)).bind(4, id).step();
}

void Store::set_stage(const std::string& id, const StageRecord& s) {
  std::lock_guard lock(mutex_);
  Statement(db_, "UPDATE stages SET state = ?, progress = ?, seconds = ?, summary = ? WHERE trial_id = ? AND name = ?")
      .bind(1, s.state).bind(2, s.progress).bind(3, s.seconds).bind(4, json_text(s.summary)).bind(5, id).bind(6, s.name).step();
  Statement(db_, "UPDATE trials SET updated_at = ? WHERE id = ?").bind(1, now_iso8601()).bind(2, id).step();
}

bool Store::delete_trial(const std::string& id) {
  std::lock_guard lock(mutex_);
  Statement(db_, "DELETE FROM stages WHERE trial_id = ?").bind(1, id).step();
  Statement d(db_, "DELETE FROM trials WHERE id = ?");
  d.bind(1, id).step();
  return sqlite3_changes(db_) > 0;
}

std::vector<std::string> Store::requeue_interrupted() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> ids;
  {
    Statement q(db_, "SELECT id FROM trials WHERE status = 'running'");
    while (q.step()) ids.push_back(q.text(0));
  }
  for (const auto& id : ids) {
    Statement(db_, "UPDATE trials SET status = 'queued', updated_at = ? WHERE id = ?").bind(1, now_iso8601()).bind(2, id).step();
    Statement(db_, "UPDATE stages SET state = 'pending', progress = 0, seconds = 0, summary = '{}' WHERE trial_id = ?").bind(1, id).step();
  }
  return ids;
}

void Store::insert_model(const ModelRecord& m) {
  std::lock_guard lock(mutex_);
  Statement(db_, "INSERT OR REPLACE INTO models (id, name, created_at, warnings, summary) VALUES (?,?,?,?,?)")
      .bind(1, m.id).bind(2, m.name).bind(3, m.created_at).bind(4, json_text(m.warnings)).bind(5, json_text(m.summary)).step();
}

std::optional<ModelRecord> Store::model(const std::string& id) {
  std::lock_guard lock(mutex_);
  Statement q(db_, "SELECT id, name, created_at, warnings, summary FROM models WHERE id = ?");
  q.bind(1, id);
  if (!q.step()) return std::nullopt;
  return ModelRecord{q.text(0), q.text(1), q.text(2), parse_or(q.text(3), json::array()), parse_or(q.text(4), json::object())};
}

std::vector<ModelRecord> Store::models() {
  std::lock_guard lock(mutex_);
  Statement q(db_, "SELECT id, name, created_at, warnings, summary FROM models ORDER BY created_at");
  std::vector<ModelRecord> out;
  while (q.step()) out.push_back({q.text(0), q.text(1), q.text(2), parse_or(q.text(3), json::array()), parse_or(q.text(4), json::object())});
  return out;
}

}  // namespace cpgait::services
