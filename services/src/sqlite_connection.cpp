#include <sqlite3.h>

#include "sql_connection.h"

namespace cpgait::services {
namespace {

class SqliteConnection : public SqlConnection {
 public:
  explicit SqliteConnection(const std::string& path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw std::runtime_error(path + ": cannot open database: " + why);
    }
    sqlite3_busy_timeout(db_, 5000);
    exec_script("PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL");
  }
  ~SqliteConnection() override { sqlite3_close(db_); }

  SqlDialect dialect() const override { return SqlDialect::kSqlite; }

  std::vector<SqlRow> query(const std::string& sql, const std::vector<SqlValue>& params) override {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &s, nullptr) != SQLITE_OK) fail("prepare", sql);
    std::unique_ptr<sqlite3_stmt, int (*)(sqlite3_stmt*)> guard(s, sqlite3_finalize);
    for (std::size_t i = 0; i < params.size(); ++i) {
      const int k = static_cast<int>(i + 1);
      if (const auto* v = std::get_if<std::string>(&params[i]))
        sqlite3_bind_text(s, k, v->c_str(), static_cast<int>(v->size()), SQLITE_TRANSIENT);
      else if (const auto* d = std::get_if<double>(&params[i]))
        sqlite3_bind_double(s, k, *d);
      else if (const auto* n = std::get_if<std::int64_t>(&params[i]))
        sqlite3_bind_int64(s, k, *n);
      else
        sqlite3_bind_null(s, k);
    }
    std::vector<SqlRow> rows;
    while (true) {
      const int rc = sqlite3_step(s);
      if (rc == SQLITE_DONE) break;
      if (rc != SQLITE_ROW) fail("step", sql);
      SqlRow row(static_cast<std::size_t>(sqlite3_column_count(s)));
      for (int c = 0; c < sqlite3_column_count(s); ++c)
        if (sqlite3_column_type(s, c) != SQLITE_NULL) {
          const auto* p = sqlite3_column_text(s, c);
          row[static_cast<std::size_t>(c)] = std::string(reinterpret_cast<const char*>(p), static_cast<std::size_t>(sqlite3_column_bytes(s, c)));
        }
      rows.push_back(std::move(row));
    }
    return rows;
  }

  void exec_script(const std::string& sql) override {
    char* err = nullptr;
    if (const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err); rc != SQLITE_OK) {
      const std::string msg = "sqlite: " + std::string(err ? err : "unknown") + " in: " + sql;
      sqlite3_free(err);
      if (rc == SQLITE_BUSY) throw SqlTransientError(msg);  // another process held the write lock past the busy timeout
      throw std::runtime_error(msg);
    }
  }

  long changes() const override { return sqlite3_changes(db_); }
  void reconnect() override {}  // a file does not drop its connection

 private:
  sqlite3* db_ = nullptr;
  [[noreturn]] void fail(const char* what, const std::string& sql) {
    const std::string msg = std::string("sqlite ") + what + ": " + sqlite3_errmsg(db_) + " in: " + sql;
    if (sqlite3_errcode(db_) == SQLITE_BUSY) throw SqlTransientError(msg);
    throw std::runtime_error(msg);
  }
};

}  // namespace

std::unique_ptr<SqlConnection> open_sqlite(const std::string& path) { return std::make_unique<SqliteConnection>(path); }

}  // namespace cpgait::services
