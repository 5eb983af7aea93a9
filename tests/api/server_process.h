#pragma once
// Real cpgait processes for API tests: `cpgait serve` on a free port of 127.0.0.1 with its own data
// folder, and `cpgait worker`s beside it; output collected, killed (gracefully or with SIGKILL) and
// restartable on the same data. With CPGAIT_TEST_STORE=postgresql, servers keep their store in a
// database of the tests' PostgreSQL (one per data folder) instead of SQLite.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "postgres/test_postgres.h"

namespace cpgait::apitest {

inline bool store_is_postgres() {
  const char* s = std::getenv("CPGAIT_TEST_STORE");
  return s && std::string(s) == "postgresql";
}

// The store of a data folder under CPGAIT_TEST_STORE=postgresql: a fresh database the first time,
// the same one when a server restarts on that folder. Empty (SQLite) otherwise.
inline std::string test_store_for(const std::string& data_dir) {
  if (!store_is_postgres()) return "";
  std::filesystem::create_directories(data_dir);
  const std::string record = data_dir + "/test-store-url";
  std::string url;
  if (std::ifstream in(record); in) std::getline(in, url);
  if (!url.empty()) return url;
  static std::atomic<int> counter{0};
  url = cpgait::testing::fresh_postgres_database("api_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::ofstream(record) << url << "\n";
  return url;
}

class ChildProcess {
 public:
  // Starts `args`; ready when its output contains `ready_text` (then `on_output` may read a port).
  ChildProcess(std::vector<std::string> args, std::string ready_text) : args_(std::move(args)), ready_(std::move(ready_text)) {}
  virtual ~ChildProcess() { stop(SIGTERM); }

  pid_t pid() const { return pid_; }
  bool running() const { return pid_ > 0; }
  std::string log() {
    std::lock_guard lock(m_);
    return log_;
  }

  void start() {
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
    ready_seen_ = false;
    pid_ = fork();
    if (pid_ == 0) {
      dup2(fds[1], STDOUT_FILENO);
      dup2(fds[1], STDERR_FILENO);
      close(fds[0]);
      std::vector<char*> argv;
      for (auto& a : args_) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(fds[1]);
    fd_ = fds[0];
    const std::size_t from = log().size();
    reader_ = std::thread([this, from] {
      char buf[4096];
      ssize_t n;
      while ((n = read(fd_, buf, sizeof buf)) > 0) {
        std::lock_guard lock(m_);
        log_.append(buf, static_cast<std::size_t>(n));
        const auto p = log_.find(ready_, from);
        if (p != std::string::npos && !ready_seen_) {
          on_ready(log_, p + ready_.size());
          ready_seen_ = true;
        }
      }
    });
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!ready_seen_ && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (!ready_seen_) {
      stop(SIGKILL);
      throw std::runtime_error(args_[1] + " did not start: " + log());
    }
  }

  // SIGTERM for a clean stop, SIGKILL for a crash.
  void stop(int sig) {
    if (pid_ > 0) {
      kill(pid_, sig);
      int status;
      waitpid(pid_, &status, 0);
      pid_ = -1;
    }
    if (reader_.joinable()) reader_.join();
    if (fd_ >= 0) close(fd_), fd_ = -1;
  }

 protected:
  virtual void on_ready(const std::string&, std::size_t) {}

 private:
  std::vector<std::string> args_;
  std::string ready_;
  pid_t pid_ = -1;
  int fd_ = -1;
  std::atomic<bool> ready_seen_{false};
  std::thread reader_;
  std::mutex m_;
  std::string log_;
};

class ServerProcess : public ChildProcess {
 public:
  // `store`: empty for the test run's choice (test_store_for), else a --store spec.
  ServerProcess(const std::string& data_dir, std::vector<std::string> extra_args = {}, const std::string& store = "")
      : ChildProcess(arguments(data_dir, std::move(extra_args), store.empty() ? test_store_for(data_dir) : store),
                     "listening on http://127.0.0.1:") {
    start();
  }
  ~ServerProcess() override { stop(SIGTERM); }
  int port() const { return port_; }

 protected:
  void on_ready(const std::string& log, std::size_t at) override { port_ = std::atoi(log.c_str() + at); }

 private:
  std::atomic<int> port_{0};
  static std::vector<std::string> arguments(const std::string& data_dir, std::vector<std::string> extra, const std::string& store) {
    std::vector<std::string> args = {CPGAIT_BINARY, "serve", "--port", "0", "--data", data_dir};
    if (!store.empty()) args.insert(args.end(), {"--store", store});
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
};

class WorkerProcess : public ChildProcess {
 public:
  WorkerProcess(const std::string& data_dir, const std::string& store, std::vector<std::string> extra_args = {})
      : ChildProcess(arguments(data_dir, store, std::move(extra_args)), " ready: ") {
    start();
  }
  ~WorkerProcess() override { stop(SIGTERM); }

 private:
  static std::vector<std::string> arguments(const std::string& data_dir, const std::string& store, std::vector<std::string> extra) {
    std::vector<std::string> args = {CPGAIT_BINARY, "worker", "--data", data_dir, "--store", store};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
};

}  // namespace cpgait::apitest
