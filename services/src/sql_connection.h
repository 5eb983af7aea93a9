#pragma once
// One database connection behind the store: SQLite (embedded) or PostgreSQL (libpq). The store writes
// its SQL once with `?` placeholders; each connection binds them its own way. Rows come back as text.
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace cpgait::services {

using SqlValue = std::variant<std::nullptr_t, std::string, double, std::int64_t>;
using SqlRow = std::vector<std::optional<std::string>>;  // nullopt: SQL NULL

enum class SqlDialect { kSqlite, kPostgres };

// A failure that a retry on a fresh connection may cure (server restarted, connection dropped,
// serialization failure); other errors are the statement's own and are not retried.
class SqlTransientError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class SqlConnection {
 public:
  virtual ~SqlConnection() = default;
  virtual SqlDialect dialect() const = 0;
  // Runs one statement; returns its rows (none for statements without results).
  virtual std::vector<SqlRow> query(const std::string& sql, const std::vector<SqlValue>& params = {}) = 0;
  // Statements without parameters, separated by ';'.
  virtual void exec_script(const std::string& sql) = 0;
  // Rows changed by the last INSERT, UPDATE or DELETE.
  virtual long changes() const = 0;
  // After a transient error: drop the session and connect again (throws SqlTransientError if down).
  virtual void reconnect() = 0;
};

// path: a file (created when absent). WAL journal, busy timeout of 5 s.
std::unique_ptr<SqlConnection> open_sqlite(const std::string& path);
// url: a libpq connection URI (postgresql://user@host:port/db?...).
std::unique_ptr<SqlConnection> open_postgres(const std::string& url);

}  // namespace cpgait::services
