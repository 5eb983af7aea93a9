#pragma once
// `cpgait serve`: the REST API under /api/v1, /healthz, /metrics, and the dashboard at /.
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace cpgait::services {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0: any free port (printed)
  std::string data_dir = "./data";
  std::string store;  // "sqlite:PATH" or "postgresql://..."; empty: sqlite:<data_dir>/cpgait.sqlite
  int workers = 2;    // trials run at once by this process; 0: API only (workers are `cpgait worker`)
  double lease_s = 10;      // s a running trial stays held after its worker's last heartbeat
  double heartbeat_s = 1;   // s between lease renewals
  std::string token;  // when set, /api/v1 needs "Authorization: Bearer <token>"
  std::size_t max_upload_bytes = std::size_t{256} << 20;
  int read_timeout_s = 60;
  std::string web_dir;  // built dashboard (web/dist); a placeholder page when absent
  std::vector<std::string> geometry_dirs;  // folders searched for models' mesh files after the model's own Geometry
};

// Runs until SIGINT/SIGTERM. Prints "listening on http://host:port" once bound.
int serve(const ServerOptions& options);

struct WorkerOptions {
  std::string store;  // as ServerOptions::store; required
  std::string data_dir = "./data";  // the folder the API server writes uploads to (shared by every machine)
  int threads = 1;    // trials run at once
  double lease_s = 10;
  double heartbeat_s = 1;
  std::string name;   // default host:pid:random
};

// `cpgait worker`: runs the store's queued trials until SIGINT/SIGTERM. Prints "worker NAME ready".
int run_worker(const WorkerOptions& options);

// The same service without a socket (for fuzzing the request handling): one raw HTTP request in,
// the raw response out. Its job runner is not started, so accepted trials stay queued.
class InProcessServer {
 public:
  explicit InProcessServer(const ServerOptions& options);
  ~InProcessServer();
  std::string handle(const std::string& raw_request);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cpgait::services
