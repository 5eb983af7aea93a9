// serve: the REST service and dashboard.
#include "commands.h"
#include "server.h"

namespace cpgait::services {

void add_serve_command(CLI::App& app) {
  auto* s = app.add_subcommand("serve",
                               "Run the REST service (API under /api/v1, dashboard at /). Data: SQLite (WAL) and one folder per\n"
                               "trial under --data. Uploads: multipart trials (markers .trc, optional grf .mot + loads .xml,\n"
                               "options JSON) and models (.osim). Stops cleanly on Ctrl-C; interrupted trials re-run on restart.");
  auto o = std::make_shared<ServerOptions>();
  auto max_mb = std::make_shared<double>(256);
  s->add_option("--port", o->port, "TCP port (0: any free port)")->capture_default_str();
  s->add_option("--host", o->host, "address to listen on")->capture_default_str();
  s->add_option("--data", o->data_dir, "data folder")->capture_default_str();
  s->add_option("--workers", o->workers, "trials processed at once")->check(CLI::Range(1, 64))->capture_default_str();
  s->add_option("--token", o->token, "require 'Authorization: Bearer <token>' on /api/v1");
  s->add_option("--max-upload-mb", *max_mb, "largest accepted request body, MB")->check(CLI::PositiveNumber)->capture_default_str();
  s->add_option("--read-timeout", o->read_timeout_s, "seconds to wait for a slow upload")->capture_default_str();
  s->add_option("--web", o->web_dir, "built dashboard folder (default: web/dist when present)");
  s->callback([o, max_mb] {
    o->max_upload_bytes = static_cast<std::size_t>(*max_mb * 1024 * 1024);
    if (o->web_dir.empty()) o->web_dir = std::string(CPGAIT_SOURCE_DIR) + "/web/dist";
    const int rc = serve(*o);
    if (rc != 0) std::exit(rc);
  });
}

}  // namespace cpgait::services
