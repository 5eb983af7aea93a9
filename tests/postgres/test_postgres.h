#pragma once
// The tests' PostgreSQL server: the one ctest's Postgres.Start fixture started
// (tests/postgres/pg_test_server.sh writes its URL to CPGAIT_TEST_POSTGRES_URL_FILE), or the URL
// in CPGAIT_TEST_POSTGRES. Each test gets a database of its own.
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "sql_connection.h"

namespace cpgait::testing {

// Empty when no server is running for the tests (or a URL left by an interrupted run answers no more).
inline std::string test_postgres_url() {
  static const std::string url = [] {
    std::string u;
    if (const char* env = std::getenv("CPGAIT_TEST_POSTGRES"); env && *env) return std::string(env);
    const char* file = std::getenv("CPGAIT_TEST_POSTGRES_URL_FILE");
    std::ifstream in(file && *file ? file : CPGAIT_TEST_POSTGRES_URL_FILE_DEFAULT);
    std::getline(in, u);
    try {
      if (!u.empty()) services::open_postgres(u);
    } catch (const std::exception&) {
      u.clear();
    }
    return u;
  }();
  return url;
}

// A fresh, empty database named `name` (lowercase letters, digits, _) on the test server; its URL.
inline std::string fresh_postgres_database(const std::string& name) {
  const std::string url = test_postgres_url();
  auto admin = services::open_postgres(url);
  admin->exec_script("DROP DATABASE IF EXISTS " + name + " WITH (FORCE)");
  admin->exec_script("CREATE DATABASE " + name);
  return url.substr(0, url.rfind('/') + 1) + name;
}

// A PostgreSQL server of one test's or benchmark's own (tests/postgres/pg_test_server.sh), stopped
// and its data removed at the end; url() is empty where the server package is not installed.
class PrivatePostgres {
 public:
  PrivatePostgres() {
    static std::atomic<int> counter{0};
    state_ = (std::filesystem::temp_directory_path() / ("cpgait_pg_state_" + std::to_string(::getpid()) + "_" + std::to_string(counter++))).string();
    script("start");
    std::ifstream in(state_ + "/url");
    std::getline(in, url_);
  }
  ~PrivatePostgres() {
    try {
      script("stop");
    } catch (const std::exception&) {
    }
    std::error_code ec;
    std::filesystem::remove_all(state_, ec);
  }
  const std::string& url() const { return url_; }
  void restart() { script("restart"); }

 private:
  std::string state_, url_;
  void script(const char* what) {
    const std::string log = state_ + ".log";
    const std::string cmd = std::string(CPGAIT_PG_TEST_SERVER) + " " + what + " " + state_ + " > " + log + " 2>&1";
    const int rc = std::system(cmd.c_str());
    std::ifstream in(log);
    const std::string output((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::remove(log.c_str());
    if (rc != 0) throw std::runtime_error(cmd + " failed (" + std::to_string(rc) + "): " + output);
  }
};

}  // namespace cpgait::testing

#define REQUIRE_POSTGRES()                                                                                                          \
  do {                                                                                                                              \
    if (cpgait::testing::test_postgres_url().empty())                                                                               \
      GTEST_SKIP() << "no PostgreSQL server for the tests: ctest starts one (Postgres.Start, tests/postgres/pg_test_server.sh) " \
                      "when the Debian package postgresql is installed; or set CPGAIT_TEST_POSTGRES";                              \
  } while (0)
