#pragma once
// A real `cpgait serve` on 127.0.0.1 for API tests: started on a free port with its own data folder,
// its output collected, killed (gracefully or with SIGKILL) and restartable on the same data.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace cpgait::apitest {

class ServerProcess {
 public:
  ServerProcess(std::string data_dir, std::vector<std::string> extra_args = {})
      : data_dir_(std::move(data_dir)), extra_(std::move(extra_args)) {
    start();
  }
  ~ServerProcess() { stop(SIGTERM); }

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string log() {
    std::lock_guard lock(m_);
    return log_;
  }

  void start() {
    int fds[2];
    if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
    pid_ = fork();
    if (pid_ == 0) {
      dup2(fds[1], STDOUT_FILENO);
      dup2(fds[1], STDERR_FILENO);
      close(fds[0]);
      std::vector<std::string> args = {CPGAIT_BINARY, "serve", "--port", "0", "--data", data_dir_};
      args.insert(args.end(), extra_.begin(), extra_.end());
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(fds[1]);
    fd_ = fds[0];
    port_ = 0;
    reader_ = std::thread([this] {
      char buf[4096];
      ssize_t n;
      while ((n = read(fd_, buf, sizeof buf)) > 0) {
        std::lock_guard lock(m_);
        log_.append(buf, static_cast<std::size_t>(n));
        const auto p = log_.find("listening on http://127.0.0.1:");
        if (p != std::string::npos && port_ == 0) port_ = std::atoi(log_.c_str() + p + 30);
      }
    });
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (port_ == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (port_ == 0) {
      stop(SIGKILL);
      throw std::runtime_error("server did not start: " + log());
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

 private:
  std::string data_dir_;
  std::vector<std::string> extra_;
  pid_t pid_ = -1;
  int fd_ = -1;
  std::atomic<int> port_{0};
  std::thread reader_;
  std::mutex m_;
  std::string log_;
};

}  // namespace cpgait::apitest
