#include "store.h"

#include <chrono>
#include <cstring>
#include <ctime>
#include <random>
#include <stdexcept>
#include <thread>

#include "output_files.h"

namespace cpgait::services {
using nlohmann::json;

namespace {

json parse_or(const std::optional<std::string>& s, json fallback) {
  if (!s || s->empty()) return fallback;
  json j = json::parse(*s, nullptr, false);
  return j.is_discarded() ? fallback : j;
}
std::string text(const std::optional<std::string>& s) { return s.value_or(""); }
double number(const std::optional<std::string>& s) { return s && !s->empty() ? std::stod(*s) : 0.0; }
long integer(const std::optional<std::string>& s) { return s && !s->empty() ? std::stol(*s) : 0; }
std::int64_t ms(double seconds) { return static_cast<std::int64_t>(seconds * 1000.0); }

// Each version's statements, in order. {real} and {now_ms} differ between SQLite and PostgreSQL;
// everything else is the same SQL on both.
struct Migration {
  int version;
  const char* sql;
};
const Migration kMigrations[] = {
    {1,
     "CREATE TABLE IF NOT EXISTS trials (id TEXT PRIMARY KEY, name TEXT, status TEXT NOT NULL, created_at TEXT, "
     "updated_at TEXT, options TEXT, error TEXT);"
     "CREATE INDEX IF NOT EXISTS trials_status ON trials(status, created_at);"
     "CREATE TABLE IF NOT EXISTS stages (trial_id TEXT NOT NULL, position INTEGER, name TEXT NOT NULL, state TEXT, "
     "progress {real}, seconds {real}, summary TEXT, PRIMARY KEY (trial_id, name));"
     "CREATE TABLE IF NOT EXISTS models (id TEXT PRIMARY KEY, name TEXT, created_at TEXT, warnings TEXT, summary TEXT)"},
    // Leases for workers on other machines, cancel requests they can see, results' checksums.
    {2,
     "ALTER TABLE trials ADD COLUMN worker TEXT;"
     "ALTER TABLE trials ADD COLUMN attempt INTEGER NOT NULL DEFAULT 0;"
     "ALTER TABLE trials ADD COLUMN lease_until_ms BIGINT;"
     "ALTER TABLE trials ADD COLUMN cancel_requested INTEGER NOT NULL DEFAULT 0;"
     "ALTER TABLE trials ADD COLUMN checksums TEXT;"
     "CREATE TABLE counters (name TEXT PRIMARY KEY, value BIGINT NOT NULL);"
     "INSERT INTO counters (name, value) VALUES ('lease_expiries', 0)"},
};

const char* kTrialColumns = "id, name, status, created_at, updated_at, options, error, worker, attempt";

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
            {"options", options}, {"stages", stages_json}, {"attempt", attempt}};
  if (!worker.empty()) j["worker"] = worker;
  if (!error.is_null()) j["error"] = error;
  return j;
}

Store::Store(const std::string& spec, int connections) {
  if (spec.rfind("postgresql://", 0) == 0 || spec.rfind("postgres://", 0) == 0) {
    dialect_ = SqlDialect::kPostgres;
    connect_ = [spec] { return open_postgres(spec); };
    max_connections_ = std::max(1, connections);
  } else {
    const std::string path = spec.rfind("sqlite:", 0) == 0 ? spec.substr(7) : spec;
    if (path.empty()) throw std::runtime_error("--store sqlite:PATH needs a path");
    dialect_ = SqlDialect::kSqlite;
    connect_ = [path] { return open_sqlite(path); };
    max_connections_ = 1;  // SQLite serialises writers; one connection behind the pool's lock
  }
  migrate();
}

Store::~Store() = default;

std::string Store::sql(const std::string& text) const {
  const bool pg = dialect_ == SqlDialect::kPostgres;
  static const std::pair<const char*, std::pair<const char*, const char*>> tokens[] = {
      {"{now_ms}", {"CAST((julianday('now') - 2440587.5) * 86400000.0 AS INTEGER)",
                    "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000 AS BIGINT)"}},
      {"{real}", {"REAL", "DOUBLE PRECISION"}},
      {"{skip_locked}", {"", "FOR UPDATE SKIP LOCKED"}},
      {"{for_update}", {"", "FOR UPDATE"}},
  };
  std::string out = text;
  for (const auto& [token, forms] : tokens)
    for (std::size_t p; (p = out.find(token)) != std::string::npos;) out.replace(p, std::strlen(token), pg ? forms.second : forms.first);
  return out;
}

void Store::with_connection(bool transaction, const std::function<void(SqlConnection&)>& f) {
  std::unique_ptr<SqlConnection> c;
  {
    std::unique_lock lock(pool_mutex_);
    pool_free_.wait(lock, [&] { return !idle_.empty() || open_connections_ < max_connections_; });
    if (!idle_.empty()) {
      c = std::move(idle_.back());
      idle_.pop_back();
    } else {
      ++open_connections_;  // opened below, outside the lock
    }
  }
  auto give_back = [&] {
    std::lock_guard lock(pool_mutex_);
    if (c) idle_.push_back(std::move(c));
    else --open_connections_;
    pool_free_.notify_one();
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  for (int attempt = 0;; ++attempt) {
    try {
      if (!c) c = connect_();
      if (transaction) c->exec_script(dialect_ == SqlDialect::kSqlite ? "BEGIN IMMEDIATE" : "BEGIN");
      try {
        f(*c);
        if (transaction) c->exec_script("COMMIT");
      } catch (...) {
        if (transaction) try {
            c->exec_script("ROLLBACK");
          } catch (...) {
          }
        throw;
      }
      give_back();
      return;
    } catch (const SqlTransientError&) {
      // The server went away (restart) or the transaction lost a race: start again on a new session.
      c.reset();
      if (std::chrono::steady_clock::now() > deadline) {
        give_back();
        throw;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(std::min(1000, 50 << std::min(attempt, 4))));
    } catch (...) {
      give_back();
      throw;
    }
  }
}

void Store::migrate() {
  with_connection(true, [&](SqlConnection& c) {
    // Two processes opening a new PostgreSQL store at once: one migrates, the other waits and sees it done.
    if (dialect_ == SqlDialect::kPostgres) c.query("SELECT pg_advisory_xact_lock(7215010)");
    c.exec_script("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
    const auto rows = c.query("SELECT MAX(version) FROM schema_version");
    int version = static_cast<int>(integer(rows.empty() ? std::nullopt : rows[0][0]));
    // A store from before versions were recorded has the first version's tables.
    if (version == 0 && dialect_ == SqlDialect::kSqlite &&
        integer(c.query("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'trials'")[0][0]) > 0)
      version = 1;
    if (version > kSchemaVersion)
      throw std::runtime_error("the store's schema version " + std::to_string(version) + " is newer than this cpgait's (" +
                               std::to_string(kSchemaVersion) + "): upgrade cpgait");
    for (const auto& m : kMigrations)
      if (m.version > version) c.exec_script(sql(m.sql));
    if (version != kSchemaVersion) {
      c.query("DELETE FROM schema_version");
      c.query("INSERT INTO schema_version (version) VALUES (?)", {std::int64_t{kSchemaVersion}});
    }
  });
}

int Store::schema_version() {
  int v = 0;
  with_connection(false, [&](SqlConnection& c) { v = static_cast<int>(integer(c.query("SELECT MAX(version) FROM schema_version")[0][0])); });
  return v;
}

void Store::insert_trial(const TrialRecord& t) {
  with_connection(true, [&](SqlConnection& c) {
    c.query("INSERT INTO trials (id, name, status, created_at, updated_at, options, error) VALUES (?,?,?,?,?,?,?)",
            {t.id, t.name, t.status, t.created_at, t.updated_at, json_text(t.options),
             t.error.is_null() ? SqlValue(nullptr) : SqlValue(json_text(t.error))});
    std::int64_t position = 0;
    for (const auto& s : t.stages)
      c.query("INSERT INTO stages (trial_id, position, name, state, progress, seconds, summary) VALUES (?,?,?,?,?,?,?)",
              {t.id, position++, s.name, s.state, s.progress, s.seconds, json_text(s.summary)});
  });
}

std::vector<TrialRecord> Store::query_trials(SqlConnection& c, const std::string& where, const std::vector<SqlValue>& args, int limit, int offset) {
  std::vector<SqlValue> params = args;
  params.emplace_back(std::int64_t{limit});
  params.emplace_back(std::int64_t{offset});
  std::vector<TrialRecord> out;
  std::map<std::string, std::size_t> index;
  for (const auto& r : c.query(std::string("SELECT ") + kTrialColumns + " FROM trials " + where +
                                   " ORDER BY created_at DESC, id LIMIT ? OFFSET ?",
                               params)) {
    TrialRecord t;
    t.id = text(r[0]);
    t.name = text(r[1]);
    t.status = text(r[2]);
    t.created_at = text(r[3]);
    t.updated_at = text(r[4]);
    t.options = parse_or(r[5], json::object());
    t.error = parse_or(r[6], nullptr);
    t.worker = text(r[7]);
    t.attempt = static_cast<int>(integer(r[8]));
    index[t.id] = out.size();
    out.push_back(std::move(t));
  }
  if (out.empty()) return out;
  // Every listed trial's stages in one query.
  std::string in = "?";
  std::vector<SqlValue> ids = {out[0].id};
  for (std::size_t i = 1; i < out.size(); ++i) in += ",?", ids.emplace_back(out[i].id);
  for (const auto& r : c.query("SELECT trial_id, name, state, progress, seconds, summary FROM stages WHERE trial_id IN (" + in +
                                   ") ORDER BY trial_id, position",
                               ids))
    out[index.at(text(r[0]))].stages.push_back({text(r[1]), text(r[2]), number(r[3]), number(r[4]), parse_or(r[5], json::object())});
  return out;
}

std::optional<TrialRecord> Store::trial(const std::string& id) {
  std::vector<TrialRecord> v;
  with_connection(false, [&](SqlConnection& c) { v = query_trials(c, "WHERE id = ?", {id}, 1, 0); });
  if (v.empty()) return std::nullopt;
  return v.front();
}

std::vector<TrialRecord> Store::trials(const std::string& status, int limit, int offset) {
  std::vector<TrialRecord> v;
  with_connection(false, [&](SqlConnection& c) {
    v = status.empty() ? query_trials(c, "", {}, limit, offset) : query_trials(c, "WHERE status = ?", {status}, limit, offset);
  });
  return v;
}

int Store::count_trials(const std::string& status) {
  long n = 0;
  with_connection(false, [&](SqlConnection& c) {
    n = integer(status.empty() ? c.query("SELECT COUNT(*) FROM trials")[0][0]
                               : c.query("SELECT COUNT(*) FROM trials WHERE status = ?", {status})[0][0]);
  });
  return static_cast<int>(n);
}

bool Store::delete_trial(const std::string& id) {
  bool deleted = false;
  with_connection(true, [&](SqlConnection& c) {
    c.query("DELETE FROM stages WHERE trial_id = ?", {id});
    deleted = !c.query("DELETE FROM trials WHERE id = ? RETURNING id", {id}).empty();
  });
  return deleted;
}

std::optional<TrialRecord> Store::claim_next(const std::string& worker, double lease_s) {
  std::string id;
  with_connection(true, [&](SqlConnection& c) {
    const auto rows = c.query(sql("UPDATE trials SET status = 'running', worker = ?, attempt = attempt + 1, cancel_requested = 0, "
                                  "lease_until_ms = {now_ms} + ?, updated_at = ? WHERE id = (SELECT id FROM trials WHERE status = "
                                  "'queued' ORDER BY created_at, id LIMIT 1 {skip_locked}) RETURNING id"),
                              {worker, ms(lease_s), now_iso8601()});
    if (!rows.empty()) id = text(rows[0][0]);
  });
  if (id.empty()) return std::nullopt;
  return trial(id);
}

Store::Lease Store::renew_lease(const std::string& id, const std::string& worker, int attempt, double lease_s) {
  Lease lease = Lease::kLost;
  with_connection(false, [&](SqlConnection& c) {
    const auto rows = c.query(sql("UPDATE trials SET lease_until_ms = {now_ms} + ? WHERE id = ? AND worker = ? AND attempt = ? AND "
                                  "status = 'running' RETURNING cancel_requested"),
                              {ms(lease_s), id, worker, std::int64_t{attempt}});
    if (!rows.empty()) lease = integer(rows[0][0]) ? Lease::kCancelRequested : Lease::kHeld;
  });
  return lease;
}

void Store::set_stage(const std::string& id, int attempt, const StageRecord& s) {
  with_connection(true, [&](SqlConnection& c) {
    const std::string now = now_iso8601();
    if (c.query("UPDATE trials SET updated_at = ? WHERE id = ? AND attempt = ? AND status = 'running' RETURNING id",
                {now, id, std::int64_t{attempt}})
            .empty())
      return;  // the attempt no longer holds the trial
    c.query("UPDATE stages SET state = ?, progress = ?, seconds = ?, summary = ? WHERE trial_id = ? AND name = ?",
            {s.state, s.progress, s.seconds, json_text(s.summary), id, s.name});
  });
}

bool Store::finish_trial(const std::string& id, const std::string& worker, int attempt, const std::string& status, const json& error,
                         const json& checksums, const std::function<void()>& publish) {
  bool held = false;
  with_connection(true, [&](SqlConnection& c) {
    held = false;  // a retried transaction starts over
    const auto rows = c.query(sql("SELECT status, worker, attempt FROM trials WHERE id = ? {for_update}"), {id});
    if (rows.empty() || text(rows[0][0]) != "running" || text(rows[0][1]) != worker || integer(rows[0][2]) != attempt) return;
    publish();
    c.query("UPDATE trials SET status = ?, error = ?, checksums = ?, worker = NULL, lease_until_ms = NULL, cancel_requested = 0, "
            "updated_at = ? WHERE id = ?",
            {status, error.is_null() ? SqlValue(nullptr) : SqlValue(json_text(error)),
             checksums.is_null() ? SqlValue(nullptr) : SqlValue(json_text(checksums)), now_iso8601(), id});
    if (status != "done")
      c.query("UPDATE stages SET state = CASE WHEN ? = 'cancelled' THEN 'cancelled' WHEN state = 'running' THEN 'failed' ELSE "
              "'skipped' END WHERE trial_id = ? AND state IN ('running', 'pending')",
              {status, id});
    held = true;
  });
  return held;
}

void Store::release_trial(const std::string& id, const std::string& worker, int attempt) {
  with_connection(true, [&](SqlConnection& c) {
    if (c.query("UPDATE trials SET status = 'queued', worker = NULL, lease_until_ms = NULL, updated_at = ? WHERE id = ? AND worker = ? "
                "AND attempt = ? AND status = 'running' AND cancel_requested = 0 RETURNING id",
                {now_iso8601(), id, worker, std::int64_t{attempt}})
            .empty())
      return;
    c.query("UPDATE stages SET state = 'pending', progress = 0, seconds = 0, summary = '{}' WHERE trial_id = ? AND state <> 'skipped'", {id});
  });
}

std::vector<std::string> Store::requeue_expired() {
  std::vector<std::string> ids;
  with_connection(true, [&](SqlConnection& c) {
    ids.clear();
    const std::string now = now_iso8601();
    // A lapsed trial that was asked to stop stays stopped.
    c.query(sql("UPDATE trials SET status = 'cancelled', worker = NULL, lease_until_ms = NULL, updated_at = ? WHERE status = "
                "'running' AND cancel_requested = 1 AND lease_until_ms < {now_ms}"),
            {now});
    for (const auto& r : c.query(sql("UPDATE trials SET status = 'queued', worker = NULL, lease_until_ms = NULL, updated_at = ? "
                                     "WHERE status = 'running' AND lease_until_ms < {now_ms} RETURNING id"),
                                 {now}))
      ids.push_back(text(r[0]));
    for (const auto& id : ids)
      c.query("UPDATE stages SET state = 'pending', progress = 0, seconds = 0, summary = '{}' WHERE trial_id = ? AND state <> 'skipped'",
              {id});
    if (!ids.empty())
      c.query("UPDATE counters SET value = value + ? WHERE name = 'lease_expiries'", {static_cast<std::int64_t>(ids.size())});
  });
  return ids;
}

std::vector<std::string> Store::requeue_running() {
  std::vector<std::string> ids;
  with_connection(true, [&](SqlConnection& c) {
    ids.clear();
    for (const auto& r : c.query("UPDATE trials SET status = 'queued', worker = NULL, lease_until_ms = NULL, updated_at = ? WHERE "
                                 "status = 'running' RETURNING id",
                                 {now_iso8601()}))
      ids.push_back(text(r[0]));
    for (const auto& id : ids)
      c.query("UPDATE stages SET state = 'pending', progress = 0, seconds = 0, summary = '{}' WHERE trial_id = ? AND state <> 'skipped'",
              {id});
  });
  return ids;
}

Store::Cancel Store::request_cancel(const std::string& id) {
  Cancel result = Cancel::kFinished;
  with_connection(true, [&](SqlConnection& c) {
    if (!c.query("UPDATE trials SET status = 'cancelled', updated_at = ? WHERE id = ? AND status = 'queued' RETURNING id", {now_iso8601(), id})
             .empty())
      result = Cancel::kCancelled;
    else if (!c.query("UPDATE trials SET cancel_requested = 1 WHERE id = ? AND status = 'running' RETURNING id", {id}).empty())
      result = Cancel::kCancelling;
    else
      result = Cancel::kFinished;
  });
  return result;
}

StoreMetrics Store::metrics() {
  StoreMetrics m;
  with_connection(false, [&](SqlConnection& c) {
    m = {};
    for (const auto& r : c.query("SELECT status, COUNT(*) FROM trials GROUP BY status")) m.trials_by_status[text(r[0])] = integer(r[1]);
    for (const auto& r : c.query("SELECT worker, COUNT(*) FROM trials WHERE status = 'running' GROUP BY worker"))
      m.running_by_worker[text(r[0])] = integer(r[1]);
    m.lease_expiries = integer(c.query("SELECT value FROM counters WHERE name = 'lease_expiries'")[0][0]);
    for (const auto& r : c.query("SELECT name, SUM(seconds), COUNT(*) FROM stages WHERE state = 'done' GROUP BY name"))
      m.stage_seconds[text(r[0])] = {number(r[1]), integer(r[2])};
  });
  return m;
}

void Store::insert_model(const ModelRecord& m) {
  with_connection(false, [&](SqlConnection& c) {
    c.query("INSERT INTO models (id, name, created_at, warnings, summary) VALUES (?,?,?,?,?) ON CONFLICT (id) DO UPDATE SET "
            "name = excluded.name, created_at = excluded.created_at, warnings = excluded.warnings, summary = excluded.summary",
            {m.id, m.name, m.created_at, json_text(m.warnings), json_text(m.summary)});
  });
}

std::optional<ModelRecord> Store::model(const std::string& id) {
  std::optional<ModelRecord> out;
  with_connection(false, [&](SqlConnection& c) {
    const auto rows = c.query("SELECT id, name, created_at, warnings, summary FROM models WHERE id = ?", {id});
    if (!rows.empty())
      out = ModelRecord{text(rows[0][0]), text(rows[0][1]), text(rows[0][2]), parse_or(rows[0][3], json::array()),
                        parse_or(rows[0][4], json::object())};
  });
  return out;
}

std::vector<ModelRecord> Store::models() {
  std::vector<ModelRecord> out;
  with_connection(false, [&](SqlConnection& c) {
    out.clear();
    for (const auto& r : c.query("SELECT id, name, created_at, warnings, summary FROM models ORDER BY created_at, id"))
      out.push_back({text(r[0]), text(r[1]), text(r[2]), parse_or(r[3], json::array()), parse_or(r[4], json::object())});
  });
  return out;
}

}  // namespace cpgait::services
