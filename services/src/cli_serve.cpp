// serve: the REST service and dashboard; worker: a process that runs a shared store's trials.
#include "commands.h"
#include "server.h"

namespace cpgait::services {

void add_serve_command(CLI::App& app) {
  auto* s = app.add_subcommand("serve",
                               "Run the REST service (API under /api/v1, dashboard at /). Data: a store (SQLite in --data by\n"
                               "default, or PostgreSQL shared with `cpgait worker` processes) and one folder per trial under\n"
                               "--data. Uploads: multipart trials (markers .trc, optional grf .mot + loads .xml, options JSON)\n"
                               "and models (.osim). Stops cleanly on Ctrl-C; interrupted trials re-run.");
  auto o = std::make_shared<ServerOptions>();
  auto max_mb = std::make_shared<double>(256);
  s->add_option("--port", o->port, "TCP port (0: any free port)")->capture_default_str();
  s->add_option("--host", o->host, "address to listen on")->capture_default_str();
  s->add_option("--data", o->data_dir, "data folder (with PostgreSQL: the folder every worker machine mounts)")->capture_default_str();
  s->add_option("--store", o->store, "sqlite:PATH (default: sqlite:<data>/cpgait.sqlite) or postgresql://user@host:port/db");
  s->add_option("--workers", o->workers, "trials processed at once by this process (0: API only; workers are `cpgait worker`)")
      ->check(CLI::Range(0, 64))->capture_default_str();
  s->add_option("--lease", o->lease_s, "s a running trial stays held after its worker's last heartbeat")->check(CLI::Range(1.0, 3600.0))
      ->capture_default_str();
  s->add_option("--heartbeat", o->heartbeat_s, "s between lease renewals and cancel checks")->check(CLI::Range(0.05, 600.0))
      ->capture_default_str();
  s->add_option("--token", o->token, "require 'Authorization: Bearer <token>' on /api/v1");
  s->add_option("--max-upload-mb", *max_mb, "largest accepted request body, MB")->check(CLI::PositiveNumber)->capture_default_str();
  s->add_option("--read-timeout", o->read_timeout_s, "seconds to wait for a slow upload")->capture_default_str();
  s->add_option("--web", o->web_dir, "built dashboard folder (default: web/dist when present)");
  s->add_option("--geometry", o->geometry_dirs, "folder of mesh files (.vtp, .stl, .obj) the models name, searched after a model's own "
                                                "uploaded geometry (repeatable)");
  s->callback([o, max_mb] {
    if (o->heartbeat_s * 2 >= o->lease_s) throw CLI::ValidationError("--heartbeat", "must be under half of --lease");
    o->max_upload_bytes = static_cast<std::size_t>(*max_mb * 1024 * 1024);
    if (o->web_dir.empty()) o->web_dir = std::string(CPGAIT_SOURCE_DIR) + "/web/dist";
    const int rc = serve(*o);
    if (rc != 0) std::exit(rc);
  });

  auto* w = app.add_subcommand("worker",
                               "Run queued trials from a shared store (PostgreSQL) until Ctrl-C. Each claimed trial is held by a\n"
                               "lease renewed every heartbeat; if this process dies, the trial re-runs elsewhere when its lease\n"
                               "runs out. Results are written under --data, the folder `cpgait serve` keeps uploads in.");
  auto wo = std::make_shared<WorkerOptions>();
  w->add_option("--store", wo->store, "postgresql://user@host:port/db (or sqlite:PATH on one machine)")->required();
  w->add_option("--data", wo->data_dir, "data folder shared with the API server")->capture_default_str();
  w->add_option("--threads", wo->threads, "trials run at once")->check(CLI::Range(1, 64))->capture_default_str();
  w->add_option("--lease", wo->lease_s, "s a running trial stays held after the last heartbeat")->check(CLI::Range(1.0, 3600.0))
      ->capture_default_str();
  w->add_option("--heartbeat", wo->heartbeat_s, "s between lease renewals and cancel checks")->check(CLI::Range(0.05, 600.0))
      ->capture_default_str();
  w->add_option("--name", wo->name, "worker name in the store and /metrics (default host:pid:random)");
  w->callback([wo] {
    if (wo->heartbeat_s * 2 >= wo->lease_s) throw CLI::ValidationError("--heartbeat", "must be under half of --lease");
    const int rc = run_worker(*wo);
    if (rc != 0) std::exit(rc);
  });
}

}  // namespace cpgait::services
