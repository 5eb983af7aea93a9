// libpq is loaded when a PostgreSQL store is first opened: linking it would load 20 more shared
// libraries (Kerberos, LDAP, TLS) into every command, doubling the start-up of `cpgait --help`.
#include <dlfcn.h>
#include <libpq-fe.h>

#include <charconv>
#include <cstring>
#include <mutex>

#include "sql_connection.h"

namespace cpgait::services {
namespace {

struct Libpq {
  decltype(&::PQconnectdb) PQconnectdb;
  decltype(&::PQstatus) PQstatus;
  decltype(&::PQerrorMessage) PQerrorMessage;
  decltype(&::PQfinish) PQfinish;
  decltype(&::PQsetNoticeProcessor) PQsetNoticeProcessor;
  decltype(&::PQexecParams) PQexecParams;
  decltype(&::PQexec) PQexec;
  decltype(&::PQresultStatus) PQresultStatus;
  decltype(&::PQresultErrorField) PQresultErrorField;
  decltype(&::PQclear) PQclear;
  decltype(&::PQcmdTuples) PQcmdTuples;
  decltype(&::PQntuples) PQntuples;
  decltype(&::PQnfields) PQnfields;
  decltype(&::PQgetisnull) PQgetisnull;
  decltype(&::PQgetvalue) PQgetvalue;
  decltype(&::PQgetlength) PQgetlength;
};

const Libpq& libpq() {
  static std::once_flag once;
  static Libpq pq{};
  static std::string failure;
  std::call_once(once, [] {
    void* h = ::dlopen("libpq.so.5", RTLD_NOW | RTLD_LOCAL);
    if (!h) {
      failure = std::string("a PostgreSQL store needs libpq (Debian package libpq5): ") + ::dlerror();
      return;
    }
    auto load = [&](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(::dlsym(h, name));
      if (!fn && failure.empty()) failure = std::string("libpq.so.5 has no ") + name;
    };
    load(pq.PQconnectdb, "PQconnectdb");
    load(pq.PQstatus, "PQstatus");
    load(pq.PQerrorMessage, "PQerrorMessage");
    load(pq.PQfinish, "PQfinish");
    load(pq.PQsetNoticeProcessor, "PQsetNoticeProcessor");
    load(pq.PQexecParams, "PQexecParams");
    load(pq.PQexec, "PQexec");
    load(pq.PQresultStatus, "PQresultStatus");
    load(pq.PQresultErrorField, "PQresultErrorField");
    load(pq.PQclear, "PQclear");
    load(pq.PQcmdTuples, "PQcmdTuples");
    load(pq.PQntuples, "PQntuples");
    load(pq.PQnfields, "PQnfields");
    load(pq.PQgetisnull, "PQgetisnull");
    load(pq.PQgetvalue, "PQgetvalue");
    load(pq.PQgetlength, "PQgetlength");
  });
  if (!failure.empty()) throw std::runtime_error(failure);
  return pq;
}

// `?` placeholders (outside quotes) become libpq's $1, $2, ...
std::string numbered_placeholders(const std::string& sql) {
  std::string out;
  out.reserve(sql.size() + 16);
  int n = 0;
  char quote = 0;
  for (const char c : sql) {
    if (quote) {
      if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '?') {
      out += '$' + std::to_string(++n);
      continue;
    }
    out += c;
  }
  return out;
}

std::string text_of(const SqlValue& v) {
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  char buf[32];
  if (const auto* d = std::get_if<double>(&v)) {
    const auto r = std::to_chars(buf, buf + sizeof buf, *d);  // shortest text that reads back exactly
    return std::string(buf, r.ptr);
  }
  return std::to_string(std::get<std::int64_t>(v));
}

// SQLSTATE classes worth a retry on a new connection: connection exceptions (08), the server
// shutting down or restarting (57P01-57P03), serialization failures and deadlocks (40001, 40P01).
bool transient_state(const char* state) {
  if (!state) return false;
  return std::strncmp(state, "08", 2) == 0 || std::strncmp(state, "57P0", 4) == 0 || std::strcmp(state, "40001") == 0 ||
         std::strcmp(state, "40P01") == 0;
}

class PostgresConnection : public SqlConnection {
 public:
  explicit PostgresConnection(std::string url) : pq_(libpq()), url_(std::move(url)) { connect(); }
  ~PostgresConnection() override { pq_.PQfinish(conn_); }

  SqlDialect dialect() const override { return SqlDialect::kPostgres; }

  std::vector<SqlRow> query(const std::string& sql, const std::vector<SqlValue>& params) override {
    std::vector<std::string> texts;
    std::vector<const char*> values;
    texts.reserve(params.size());
    for (const auto& p : params) {
      if (std::holds_alternative<std::nullptr_t>(p)) {
        values.push_back(nullptr);
        continue;
      }
      texts.push_back(text_of(p));
      values.push_back(texts.back().c_str());
    }
    const std::string numbered = numbered_placeholders(sql);
    PGresult* r = pq_.PQexecParams(conn_, numbered.c_str(), static_cast<int>(values.size()), nullptr, values.data(), nullptr, nullptr, 0);
    std::unique_ptr<PGresult, void (*)(PGresult*)> guard(r, pq_.PQclear);
    check(r, sql);
    changes_ = std::atol(pq_.PQcmdTuples(r));
    std::vector<SqlRow> rows;
    const int nr = pq_.PQntuples(r), nc = pq_.PQnfields(r);
    rows.reserve(static_cast<std::size_t>(nr));
    for (int i = 0; i < nr; ++i) {
      SqlRow row(static_cast<std::size_t>(nc));
      for (int c = 0; c < nc; ++c)
        if (!pq_.PQgetisnull(r, i, c)) row[static_cast<std::size_t>(c)] = std::string(pq_.PQgetvalue(r, i, c), static_cast<std::size_t>(pq_.PQgetlength(r, i, c)));
      rows.push_back(std::move(row));
    }
    return rows;
  }

  void exec_script(const std::string& sql) override {
    PGresult* r = pq_.PQexec(conn_, sql.c_str());
    std::unique_ptr<PGresult, void (*)(PGresult*)> guard(r, pq_.PQclear);
    check(r, sql);
  }

  long changes() const override { return changes_; }

  void reconnect() override {
    pq_.PQfinish(conn_);
    conn_ = nullptr;
    connect();
  }

 private:
  const Libpq& pq_;
  std::string url_;
  PGconn* conn_ = nullptr;
  long changes_ = 0;

  void connect() {
    conn_ = pq_.PQconnectdb(url_.c_str());
    if (pq_.PQstatus(conn_) != CONNECTION_OK) {
      const std::string msg = std::string("postgresql: cannot connect: ") + pq_.PQerrorMessage(conn_);
      pq_.PQfinish(conn_);
      conn_ = nullptr;
      throw SqlTransientError(msg);
    }
    // Notices (CREATE ... IF NOT EXISTS on existing objects) are not errors; keep them off stderr.
    pq_.PQsetNoticeProcessor(conn_, [](void*, const char*) {}, nullptr);
  }

  void check(PGresult* r, const std::string& sql) {
    const ExecStatusType st = r ? pq_.PQresultStatus(r) : PGRES_FATAL_ERROR;
    if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) return;
    const char* state = r ? pq_.PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
    const std::string msg = std::string("postgresql: ") + (conn_ ? pq_.PQerrorMessage(conn_) : "no connection") + " in: " + sql;
    if (!conn_ || pq_.PQstatus(conn_) != CONNECTION_OK || transient_state(state)) throw SqlTransientError(msg);
    throw std::runtime_error(msg);
  }
};

}  // namespace

std::unique_ptr<SqlConnection> open_postgres(const std::string& url) { return std::make_unique<PostgresConnection>(url); }

}  // namespace cpgait::services
