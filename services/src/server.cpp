#include "server.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/model/osim_reader.h"
#include "jobs.h"
#include "output_files.h"
#include "pipeline.h"
#include "mesh_files.h"
#include "report.h"
#include "review_data.h"
#include "zip_archive.h"

// Last: httplib pulls in <resolv.h>, whose `_res` macro breaks Eigen headers included after it.
#include <httplib.h>

namespace cpgait::services {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

httplib::Server* g_server = nullptr;
void on_signal(int) {
  if (g_server) g_server->stop();
}

void send_json(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(json_text(body), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& code, const std::string& message,
                const std::string& field = "", int line = 0) {
  json e = {{"code", code}, {"message", message}};
  if (!field.empty()) e["field"] = field;
  if (line > 0) e["line"] = line;
  send_json(res, status, {{"error", e}});
}

void send_input_error(httplib::Response& res, const InputError& e, const std::string& part) {
  json err = {{"code", "invalid_input"}, {"message", e.what()}, {"part", part}};
  if (!e.field().empty()) err["field"] = e.field();
  if (e.line() > 0) err["line"] = e.line();
  send_json(res, 422, {{"error", err}});
}

// A .sto/.mot as compact columns: labels and one array per column.
json table_json(const std::string& file, const Storage& s) {
  json columns = json::array();
  for (int c = 0; c < s.num_columns(); ++c) {
    std::vector<double> col(s.data.col(c).data(), s.data.col(c).data() + s.num_rows());
    columns.push_back(col);
  }
  json j = {{"file", file}, {"labels", s.labels}, {"columns", columns}, {"rows", s.num_rows()}};
  if (s.in_degrees) j["in_degrees"] = *s.in_degrees;
  return j;
}

class Api {
 public:
  Api(const ServerOptions& o, Store& store, ChangeSignal& changes, std::atomic<long>& requests, JobRunner& jobs)
      : o_(o), store_(store), changes_(changes), requests_(requests), jobs_(jobs) {}

  void install(httplib::Server& s) {
    s.Get("/healthz", [&](const auto&, auto& res) { send_json(res, 200, {{"status", "ok"}}); });
    s.Get("/metrics", [&](const auto&, auto& res) { metrics(res); });
    s.Get("/api/v1/options/schema", [&](const auto& req, auto& res) { if (auth(req, res)) send_json(res, 200, pipeline_options_schema()); });
    s.Get("/api/v1/stages", [&](const auto& req, auto& res) { if (auth(req, res)) send_json(res, 200, {{"stages", pipeline_stages_json()}}); });
    s.Get("/api/v1/models", [&](const auto& req, auto& res) { if (auth(req, res)) list_models(res); });
    s.Get(R"(/api/v1/models/([^/]+)/meshes/([^/]+))",
          [&](const auto& req, auto& res) { if (auth(req, res)) mesh(req.matches[1], req.matches[2], res); });
    s.Post("/api/v1/models", [&](const auto& req, auto& res) { if (auth(req, res)) upload_model(req, res); });
    s.Post("/api/v1/trials", [&](const auto& req, auto& res) { if (auth(req, res)) upload_trial(req, res); });
    s.Get("/api/v1/trials", [&](const auto& req, auto& res) { if (auth(req, res)) list_trials(req, res); });
    s.Get(R"(/api/v1/trials/([^/]+))", [&](const auto& req, auto& res) { if (auth(req, res)) get_trial(req.matches[1], res); });
    s.Delete(R"(/api/v1/trials/([^/]+))", [&](const auto& req, auto& res) { if (auth(req, res)) delete_trial(req.matches[1], res); });
    s.Post(R"(/api/v1/trials/([^/]+)/cancel)", [&](const auto& req, auto& res) { if (auth(req, res)) cancel(req.matches[1], res); });
    s.Get(R"(/api/v1/trials/([^/]+)/events)", [&](const auto& req, auto& res) { if (auth(req, res)) sse(req.matches[1], res); });
    s.Get(R"(/api/v1/trials/([^/]+)/results/([^/]+))",
          [&](const auto& req, auto& res) { if (auth(req, res)) results(req.matches[1], req.matches[2], res); });
    s.Get(R"(/api/v1/trials/([^/]+)/kinematics)",
          [&](const auto& req, auto& res) {
            if (auth(req, res)) kinematics(req.matches[1], req.has_param("source") ? req.get_param_value("source") : "ik", res);
          });
    s.Get(R"(/api/v1/trials/([^/]+)/report)",
          [&](const auto& req, auto& res) { if (auth(req, res)) report(req.matches[1], res); });
    s.Get(R"(/api/v1/trials/([^/]+)/cycles)",
          [&](const auto& req, auto& res) { if (auth(req, res)) cycles(req.matches[1], res); });
    s.Get(R"(/api/v1/trials/([^/]+)/files/(.+))",
          [&](const auto& req, auto& res) { if (auth(req, res)) file(req.matches[1], req.matches[2], res); });
    s.Get(R"(/api/v1/.*)", [&](const auto&, auto& res) { send_error(res, 404, "not_found", "no such endpoint"); });
    if (!o_.web_dir.empty() && fs::exists(o_.web_dir)) {
      s.set_mount_point("/", o_.web_dir);
    } else {
      s.Get("/", [](const auto&, auto& res) {
        res.set_content("<!doctype html><title>cpgait</title><h1>cpgait</h1><p>The REST API is at <code>/api/v1</code> "
                        "(trials, models, results). The review dashboard is not built yet.</p>",
                        "text/html");
      });
    }
  }

 private:
  const ServerOptions& o_;
  Store& store_;
  ChangeSignal& changes_;
  std::atomic<long>& requests_;
  JobRunner& jobs_;

  bool auth(const httplib::Request& req, httplib::Response& res) {
    if (o_.token.empty()) return true;
    if (req.get_header_value("Authorization") == "Bearer " + o_.token) return true;
    send_error(res, 401, "unauthorized", "missing or wrong token: send 'Authorization: Bearer <token>'", "Authorization");
    return false;
  }

  static bool valid_id(const std::string& id) {
    return id.size() == 16 && std::all_of(id.begin(), id.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)); });
  }

  std::optional<TrialRecord> find(const std::string& id, httplib::Response& res) {
    std::optional<TrialRecord> t;
    if (valid_id(id)) t = store_.trial(id);
    if (!t) send_error(res, 404, "not_found", "no trial with id '" + id + "'", "id");
    return t;
  }

  // From the store, so that every worker process' trials are counted.
  void metrics(httplib::Response& res) {
    const StoreMetrics m = store_.metrics();
    std::string out = "# HELP cpgait_trials Trials by status.\n# TYPE cpgait_trials gauge\n";
    for (const char* s : {"queued", "running", "done", "failed", "cancelled"})
      out += std::string("cpgait_trials{status=\"") + s + "\"} " + std::to_string(m.trials_by_status.count(s) ? m.trials_by_status.at(s) : 0) + "\n";
    out += "# HELP cpgait_queue_depth Trials waiting for a worker.\n# TYPE cpgait_queue_depth gauge\n";
    out += "cpgait_queue_depth " + std::to_string(m.trials_by_status.count("queued") ? m.trials_by_status.at("queued") : 0) + "\n";
    out += "# HELP cpgait_worker_running_trials Trials each worker holds a lease on.\n# TYPE cpgait_worker_running_trials gauge\n";
    for (const auto& [worker, n] : m.running_by_worker)
      out += "cpgait_worker_running_trials{worker=\"" + worker + "\"} " + std::to_string(n) + "\n";
    out += "# HELP cpgait_lease_expiries_total Running trials re-queued because their worker stopped renewing.\n"
           "# TYPE cpgait_lease_expiries_total counter\n";
    out += "cpgait_lease_expiries_total " + std::to_string(m.lease_expiries) + "\n";
    out += "# HELP cpgait_stage_seconds Stage run time over the stored trials.\n# TYPE cpgait_stage_seconds summary\n";
    for (const auto& [stage, v] : m.stage_seconds) {
      out += "cpgait_stage_seconds_sum{stage=\"" + stage + "\"} " + std::to_string(v.first) + "\n";
      out += "cpgait_stage_seconds_count{stage=\"" + stage + "\"} " + std::to_string(v.second) + "\n";
    }
    out += "# HELP cpgait_http_requests_total Requests served by this process.\n# TYPE cpgait_http_requests_total counter\n";
    out += "cpgait_http_requests_total " + std::to_string(requests_.load()) + "\n";
    res.set_content(out, "text/plain; version=0.0.4");
  }

  void list_models(httplib::Response& res) {
    json out = json::array();
    for (const auto& m : store_.models())
      out.push_back({{"id", m.id}, {"name", m.name}, {"created_at", m.created_at}, {"warnings", m.warnings}, {"summary", m.summary}});
    send_json(res, 200, {{"models", out}});
  }

  // A mesh file a model names, as triangles (positions in m, three indices per triangle): from the
  // model's uploaded geometry, else the --geometry folders.
  void mesh(const std::string& model_id, const std::string& file, httplib::Response& res) {
    if (!store_.model(model_id)) return send_error(res, 404, "not_found", "no model with id '" + model_id + "'", "model");
    if (!is_safe_file_name(file)) return send_error(res, 400, "bad_file_name", "unsafe file name '" + file + "'", "file");
    std::vector<fs::path> places = {fs::path(o_.data_dir) / "models" / model_id / "Geometry" / file};
    for (const auto& d : o_.geometry_dirs) places.push_back(fs::path(d) / file);
    for (const auto& p : places) {
      if (!fs::is_regular_file(p)) continue;
      try {
        const TriangleMesh m = read_mesh_file(p.string());
        std::vector<double> positions(m.positions.size());
        for (std::size_t i = 0; i < positions.size(); ++i) positions[i] = std::round(m.positions[i] * 1e6) / 1e6;
        res.set_header("Cache-Control", "max-age=3600");
        return send_json(res, 200, {{"file", file}, {"positions", positions}, {"triangles", m.triangles}});
      } catch (const InputError& e) {
        return send_error(res, 422, "invalid_input", e.what(), e.field(), e.line());
      }
    }
    send_error(res, 404, "not_found", "mesh '" + file + "' is in neither the model's geometry nor a --geometry folder", "file");
  }

  void upload_model(const httplib::Request& req, httplib::Response& res) {
    if (!req.is_multipart_form_data() || !req.has_file("model"))
      return send_error(res, 400, "bad_request", "expected multipart/form-data with a 'model' part (the .osim, or a .zip of it and its Geometry folder)", "model");
    const auto part = req.get_file_value("model");
    std::string name = part.filename.empty() ? "model.osim" : part.filename;
    if (!is_safe_file_name(name)) return send_error(res, 400, "bad_file_name", "unsafe file name '" + name + "'", "model");
    // Written to <id>.tmp, validated there, then renamed into place: a rejected model leaves nothing.
    const std::string id = new_id();
    const fs::path tmp = fs::path(o_.data_dir) / "models" / (id + ".tmp"), dir = fs::path(o_.data_dir) / "models" / id;
    std::string part_name = "model";
    try {
      // Mesh files for the 3-D view: `geometry` parts, and those of a zipped model (its Geometry folder).
      struct MeshPart {
        std::string file, label, content;  // label: where it came from, for messages
      };
      std::vector<MeshPart> meshes;
      json notes = json::array();
      std::string osim = part.content;
      if (looks_like_zip(part.content)) {
        ZipReadOptions zo;
        zo.max_total_bytes = o_.max_upload_bytes;
        std::vector<std::string> models, ignored;
        const std::string zip_name = name;
        for (ZipEntry& e : read_zip(part.content, zip_name, zo)) {
          const std::string base = e.path.substr(e.path.rfind('/') + 1);  // npos + 1 == 0
          if (text::lower_extension(base) == "osim") {
            models.push_back(e.path);
            name = base;
            osim = std::move(e.content);
          } else if (is_mesh_file_name(base)) {
            meshes.push_back({base, zip_name + ":" + e.path, std::move(e.content)});
          } else {
            ignored.push_back(e.path);
          }
        }
        if (models.size() != 1)
          throw InputError(zip_name, 0, "model", models.empty() ? "the archive holds no .osim model"
                                                                : "the archive holds " + std::to_string(models.size()) + " .osim models (" +
                                                                      models[0] + ", " + models[1] + "…): zip one model per upload");
        if (!ignored.empty())
          notes.push_back(zip_name + ": ignored " + std::to_string(ignored.size()) + " file(s) that are neither the model nor a mesh, e.g. " + ignored[0]);
      }
      const auto parts = req.files.equal_range("geometry");
      for (auto it = parts.first; it != parts.second; ++it) meshes.push_back({it->second.filename, it->second.filename, it->second.content});
      ensure_directory(tmp.string());
      write_text_atomic((tmp / "model.osim").string(), osim);
      OsimReadOptions ro;
      if (req.has_file("markerset")) {
        part_name = "markerset";
        write_text_atomic((tmp / "markerset.xml").string(), req.get_file_value("markerset").content);
        ro.marker_set_file = (tmp / "markerset.xml").string();
      }
      // Each mesh is checked, then kept in the model's Geometry folder; the first of a name wins.
      part_name = "geometry";
      std::set<std::string> kept;
      for (const MeshPart& mesh : meshes) {
        if (!is_safe_file_name(mesh.file)) throw InputError(mesh.label, 0, "geometry", "unsafe or missing mesh file name");
        parse_mesh(mesh.content, mesh.label);
        if (!kept.insert(mesh.file).second) {
          notes.push_back("two meshes named " + mesh.file + "; kept the first");
          continue;
        }
        ensure_directory((tmp / "Geometry").string());
        write_text_atomic((tmp / "Geometry" / mesh.file).string(), mesh.content);
      }
      part_name = "model";
      const OsimReadResult r = parse_osim(osim, name, ro);
      for (const auto& w : r.warnings) notes.push_back(w);
      const ModelRecord m{id, name, now_iso8601(), notes,
                          {{"bodies", r.model.bodies.size() - 1}, {"coordinates", r.model.num_coordinates()},
                           {"markers", r.model.markers.size()}, {"muscles", r.model.muscles.size()},
                           {"mass_kg", r.model.total_mass_kg()}, {"markerset", !ro.marker_set_file.empty()},
                           {"meshes", kept.size()}}};
      fs::rename(tmp, dir);
      store_.insert_model(m);
      send_json(res, 201, {{"id", id}, {"warnings", m.warnings}, {"summary", m.summary}});
    } catch (const InputError& e) {
      std::error_code ec;
      fs::remove_all(tmp, ec);
      send_input_error(res, e, part_name == "geometry" ? part_name : e.file().find("markerset") != std::string::npos ? "markerset" : part_name);
    }
  }

  void upload_trial(const httplib::Request& req, httplib::Response& res) {
    if (!check_trial_parts(req, res)) return;
    const bool footage = req.files.count("videos") > 0;
    std::optional<PipelineOptions> options = trial_options(req, res);
    if (!options) return;
    TrialInputs in = trial_inputs(req, *options, footage);
    // Everything is written into a temporary folder, validated there, and appears complete (rename).
    TrialRecord t;
    t.id = new_id();
    const fs::path tmp = fs::path(o_.data_dir) / "trials" / (t.id + ".tmp"), dir = jobs_.trial_dir(t.id);
    auto discard = [&] {
      std::error_code ec;
      fs::remove_all(tmp, ec);
    };
    try {
      save_trial_inputs(req, tmp / "inputs", in, footage);
    } catch (const std::exception& e) {
      discard();
      return send_error(res, 500, "storage_failed", e.what());
    }
    try {
      validate_inputs(in, *options);
    } catch (const InputError& e) {
      discard();
      // Errors name the uploaded file, not where the server keeps it.
      const std::string shown = fs::path(e.file()).filename().string();
      return send_input_error(res, InputError(shown, e.line(), e.field(), e.message()), uploaded_part(e.file(), in, footage));
    }
    t.name = in.name;
    t.status = "queued";
    t.created_at = t.updated_at = now_iso8601();
    t.options = options->to_json();
    for (const Stage* s : options->table())
      if (s->applies(in)) t.stages.push_back({s->name(), options->runs(*s, in) ? "pending" : "skipped", 0, 0, json::object()});
    try {
      fs::rename(tmp, dir);
      store_.insert_trial(t);
    } catch (const std::exception& e) {
      discard();
      std::error_code ec;
      fs::remove_all(dir, ec);
      return send_error(res, 500, "storage_failed", e.what());
    }
    jobs_.wake();
    const std::string base = "/api/v1/trials/" + t.id;
    send_json(res, 202, {{"id", t.id}, {"status", t.status}, {"url", base}, {"events", base + "/events"}, {"results", base + "/results"}});
  }

  // The upload's parts are there and safely named; otherwise answers 400 and returns false.
  static bool check_trial_parts(const httplib::Request& req, httplib::Response& res) {
    if (!req.is_multipart_form_data()) {
      send_error(res, 400, "bad_request", "expected multipart/form-data with a 'markers' part (.trc) or 'videos' parts");
      return false;
    }
    const auto video_parts = req.files.equal_range("videos");
    const bool footage = video_parts.first != video_parts.second;
    if (!footage && !req.has_file("markers")) {
      send_error(res, 400, "missing_part", "a 'markers' part (.trc), or 'videos' parts with 'calibration' and 'tags', is required", "markers");
      return false;
    }
    if (footage && req.has_file("markers")) {
      send_error(res, 400, "bad_request", "give either 'markers' or 'videos', not both", "markers");
      return false;
    }
    for (const char* p : {"calibration", "tags"})
      if (footage && !req.has_file(p)) {
        send_error(res, 400, "missing_part", std::string("videos need a '") + p + "' part", p);
        return false;
      }
    if (req.has_file("scale_setup") && !req.has_file("static")) {
      send_error(res, 400, "missing_part", "a 'scale_setup' needs the subject's 'static' trial", "static");
      return false;
    }
    for (const char* p : {"markers", "grf", "loads", "options", "calibration", "tags", "static", "scale_setup", "cmc_tasks", "cmc_actuators",
                          "cmc_constraints"})
      if (req.has_file(p) && !req.get_file_value(p).filename.empty() && !is_safe_file_name(req.get_file_value(p).filename)) {
        send_error(res, 400, "bad_file_name", "unsafe file name '" + req.get_file_value(p).filename + "'", p);
        return false;
      }
    for (auto it = video_parts.first; it != video_parts.second; ++it)
      if (!is_safe_file_name(it->second.filename)) {
        send_error(res, 400, "bad_file_name", "unsafe or missing video file name '" + it->second.filename + "' (name each video after its camera)", "videos");
        return false;
      }
    return true;
  }

  // The options part, parsed and checked against the models stored; otherwise answers and returns none.
  std::optional<PipelineOptions> trial_options(const httplib::Request& req, httplib::Response& res) {
    auto refuse = [&res](int status, const std::string& code, const std::string& message, const std::string& field) {
      send_error(res, status, code, message, field);
      return std::nullopt;
    };
    const std::string text = req.has_file("options") ? req.get_file_value("options").content : "";
    json parsed;
    try {
      parsed = text.empty() ? json::object() : json::parse(text);
    } catch (const json::exception& e) {  // parse errors, and numbers past double's range
      return refuse(400, "malformed_json", std::string("options: ") + e.what(), "options");
    }
    if (!parsed.is_object()) return refuse(400, "malformed_json", "options: expected a JSON object", "options");
    std::optional<PipelineOptions> options;
    try {
      options = PipelineOptions::from_json(parsed, "options");
    } catch (const InputError& e) {
      send_input_error(res, e, "options");
      return std::nullopt;
    }
    if (options->model_id.empty()) return refuse(422, "invalid_input", "options must name a model: {\"model\": \"<model id>\"}", "model");
    for (const auto& [field, id] : {std::pair<std::string, std::string>{"model", options->model_id}, {"scale_muscles_from", options->scale_muscles_from_id}})
      if (!id.empty() && !store_.model(id))
        return refuse(422, "unknown_model", "no model with id '" + id + "' (upload one to /api/v1/models)", field);
    options->inputs = json::object();
    return options;
  }

  TrialInputs trial_inputs(const httplib::Request& req, const PipelineOptions& options, bool footage) const {
    TrialInputs in;
    const std::string first_name = footage ? std::string("capture") : req.get_file_value("markers").filename;
    in.name = first_name.empty() ? "trial" : fs::path(first_name).stem().string();
    if (!is_safe_file_name(in.name)) in.name = "trial";
    in.model_path = jobs_.model_path(options.model_id);
    if (!options.scale_muscles_from_id.empty()) in.generic_model_path = jobs_.model_path(options.scale_muscles_from_id);
    in.marker_set_path = jobs_.marker_set_path(options.model_id);
    if (!footage) {
      const auto markers = req.get_file_value("markers");
      in.markers = markers.content;
      in.markers_name = markers.filename.empty() ? "markers" : markers.filename;
    }
    if (req.has_file("grf")) in.grf = req.get_file_value("grf").content, in.grf_name = req.get_file_value("grf").filename;
    if (req.has_file("loads")) in.loads = req.get_file_value("loads").content, in.loads_name = req.get_file_value("loads").filename;
    if (in.grf_name.empty()) in.grf_name = "grf";
    if (in.loads_name.empty()) in.loads_name = "loads";
    // A static trial: the model is the generic one, scaled first by the scale stage.
    if (req.has_file("static")) {
      const auto st = req.get_file_value("static");
      in.static_markers = st.content;
      in.static_name = st.filename.empty() ? "static" : st.filename;
    }
    if (req.has_file("scale_setup")) {
      const auto su = req.get_file_value("scale_setup");
      in.scale_setup = su.content;
      in.scale_setup_name = su.filename.empty() ? "scale_setup" : su.filename;
    }
    for (const CmcFilePart& f : kCmcFileParts)
      if (req.has_file(f.part)) {
        const auto up = req.get_file_value(f.part);
        in.*f.content = up.content;
        in.*f.name = up.filename.empty() ? f.part : up.filename;
      }
    return in;
  }

  // The uploaded files under inputs/ (where the worker reads them); footage paths are filled into `in`.
  static void save_trial_inputs(const httplib::Request& req, const fs::path& inputs, TrialInputs& in, bool footage) {
    ensure_directory(inputs.string());
    if (footage) {
      ensure_directory((inputs / "videos").string());
      const auto video_parts = req.files.equal_range("videos");
      for (auto it = video_parts.first; it != video_parts.second; ++it)
        write_text_atomic((inputs / "videos" / it->second.filename).string(), it->second.content);
      const auto cal = req.get_file_value("calibration");
      std::string ext = fs::path(cal.filename).extension().string();
      if (ext != ".yml" && ext != ".yaml" && ext != ".xml") ext = ".json";
      write_text_atomic((inputs / ("calibration" + ext)).string(), cal.content);
      write_text_atomic((inputs / "tags.json").string(), req.get_file_value("tags").content);
      load_footage_inputs(inputs.string(), in);
    } else {
      write_text_atomic((inputs / "markers.trc").string(), in.markers);
    }
    if (!in.grf.empty()) {
      write_text_atomic((inputs / "grf.mot").string(), in.grf);
      write_text_atomic((inputs / "loads.xml").string(), in.loads);
    }
    if (!in.static_markers.empty()) write_text_atomic((inputs / "static.trc").string(), in.static_markers);
    if (!in.scale_setup.empty()) write_text_atomic((inputs / "scale_setup.xml").string(), in.scale_setup);
    for (const CmcFilePart& f : kCmcFileParts)
      if (!(in.*f.content).empty()) write_text_atomic((inputs / (std::string(f.part) + ".xml")).string(), in.*f.content);
  }

  // Which upload part a validation error is about.
  static std::string uploaded_part(const std::string& file, const TrialInputs& in, bool footage) {
    if (file == in.grf_name) return "grf";
    if (file == in.loads_name) return "loads";
    if (!in.static_name.empty() && file == in.static_name) return "static";
    if (!in.scale_setup_name.empty() && file == in.scale_setup_name) return "scale_setup";
    for (const CmcFilePart& f : kCmcFileParts)
      if (!(in.*f.name).empty() && file == in.*f.name) return f.part;
    if (footage && file == in.calibration_path) return "calibration";
    if (footage && file == in.tags_path) return "tags";
    return footage ? "videos" : "markers";
  }

  void list_trials(const httplib::Request& req, httplib::Response& res) {
    const std::string status = req.has_param("status") ? req.get_param_value("status") : "";
    if (!status.empty() && status != "queued" && status != "running" && status != "done" && status != "failed" && status != "cancelled")
      return send_error(res, 400, "bad_parameter", "status must be queued, running, done, failed or cancelled", "status");
    int limit = 50, offset = 0;
    try {
      if (req.has_param("limit")) limit = std::clamp(std::stoi(req.get_param_value("limit")), 1, 500);
      if (req.has_param("offset")) offset = std::max(0, std::stoi(req.get_param_value("offset")));
    } catch (const std::exception&) {
      return send_error(res, 400, "bad_parameter", "limit and offset must be whole numbers", "limit");
    }
    json items = json::array();
    for (const auto& t : store_.trials(status, limit, offset)) items.push_back(t.to_json());
    send_json(res, 200, {{"trials", items}, {"total", store_.count_trials(status)}, {"limit", limit}, {"offset", offset}});
  }

  void get_trial(const std::string& id, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    json j = t->to_json();
    j["files"] = json::array();
    std::error_code ec;
    if (t->status == "done")
      for (const auto& e : fs::directory_iterator(result_dir(*t), ec)) j["files"].push_back(e.path().filename().string());
    std::sort(j["files"].begin(), j["files"].end());
    send_json(res, 200, j);
  }

  void delete_trial(const std::string& id, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    jobs_.cancel(id);
    store_.delete_trial(id);
    changes_.notify();
    std::error_code ec;
    fs::remove_all(jobs_.trial_dir(id), ec);
    res.status = 204;
  }

  void cancel(const std::string& id, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    if (!jobs_.cancel(id))
      return send_error(res, 409, "not_cancellable", "trial is already " + t->status, "status");
    send_json(res, 202, {{"id", id}, {"status", "cancelling"}});
  }

  // Progress as Server-Sent Events, from the store: whichever process runs the trial, its stage
  // changes show up here (at once when this process runs it, else within the 250 ms poll).
  void sse(const std::string& id, httplib::Response& res) {
    if (!find(id, res)) return;
    res.set_header("Cache-Control", "no-cache");
    struct Seen {
      bool snapshot = false;
      std::map<std::string, std::pair<std::string, double>> stages;  // name -> (state, progress)
      std::string status;
      std::uint64_t version = 0;
      std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
    };
    res.set_chunked_content_provider("text/event-stream", [this, id, seen = Seen{}](size_t, httplib::DataSink& sink) mutable {
      auto send = [&](const char* event, const json& data) {
        seen.last_write = std::chrono::steady_clock::now();
        const std::string msg = std::string("event: ") + event + "\ndata: " + json_text(data) + "\n\n";
        return sink.write(msg.data(), msg.size());
      };
      auto finished = [](const std::string& s) { return s == "done" || s == "failed" || s == "cancelled"; };
      const auto t = store_.trial(id);
      if (!t) {  // deleted
        sink.done();
        return true;
      }
      if (!seen.snapshot) {
        seen.snapshot = true;
        seen.status = t->status;
        for (const auto& s : t->stages) seen.stages[s.name] = {s.state, s.progress};
        if (!send("snapshot", t->to_json())) return false;
      } else {
        for (const auto& s : t->stages) {
          auto& last = seen.stages[s.name];
          if (last.first == s.state && last.second == s.progress) continue;
          last = {s.state, s.progress};
          if (!send("progress", {{"status", "running"}, {"stage", s.name}, {"state", s.state}, {"progress", s.progress}})) return false;
        }
        if (t->status != seen.status) {
          seen.status = t->status;
          json e = {{"status", t->status}};
          if (!t->error.is_null()) e["error"] = t->error;
          if (!send("progress", e)) return false;
        }
      }
      if (finished(t->status)) {
        send("end", {{"status", t->status}});
        sink.done();
        return true;
      }
      seen.version = changes_.wait(seen.version, 250);
      if (std::chrono::steady_clock::now() - seen.last_write > std::chrono::seconds(15)) {
        seen.last_write = std::chrono::steady_clock::now();
        const std::string beat = ": keep-alive\n\n";
        return sink.write(beat.data(), beat.size());
      }
      return true;
    });
  }

  // A finished trial's results, or the running attempt's partial ones.
  fs::path result_dir(const TrialRecord& t) {
    const fs::path dir = jobs_.trial_dir(t.id);
    return fs::exists(dir / "results") ? dir / "results" : dir / ("work-" + std::to_string(t.attempt));
  }

  void results(const std::string& id, const std::string& stage, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    const Stage* known = find_stage(stage);
    if (!known) {
      std::string names;
      for (const Stage* s : pipeline_stages()) names += (names.empty() ? "" : ", ") + s->name();
      return send_error(res, 404, "unknown_stage", "stages are " + names, "stage");
    }
    const auto s = std::find_if(t->stages.begin(), t->stages.end(), [&](const StageRecord& r) { return r.name == stage; });
    if (s == t->stages.end() || s->state != "done")
      return send_error(res, 409, "not_ready", "stage '" + stage + "' is " + (s == t->stages.end() ? "absent" : s->state), "stage");
    json tables = json::array();
    try {
      for (const auto& suffix : known->tables()) {
        const std::string file = t->name + suffix;
        tables.push_back(table_json(file, read_storage((result_dir(*t) / file).string())));
      }
    } catch (const std::exception& e) {
      return send_error(res, 409, "not_ready", std::string("results are not readable yet: ") + e.what());
    }
    send_json(res, 200, {{"trial", id}, {"stage", stage}, {"summary", s->summary}, {"tables", tables}});
  }

  // What the review endpoints read of a trial whose IK is done: the model IK ran on (a scaled
  // trial's, markers placed), its marker set, the markers, and the ground reactions when there are any.
  struct ReviewInputs {
    std::string model, marker_set, markers_file, grf, loads;
  };
  // Without IK, none (answered with a 409 when `res` is given).
  std::optional<ReviewInputs> review_inputs(const TrialRecord& t, httplib::Response* res) {
    const auto ik = std::find_if(t.stages.begin(), t.stages.end(), [](const StageRecord& s) { return s.name == "ik"; });
    if (ik == t.stages.end() || ik->state != "done") {
      if (res) send_error(*res, 409, "not_ready", "inverse kinematics is not done yet", "stage");
      return std::nullopt;
    }
    const fs::path dir = jobs_.trial_dir(t.id), inputs = dir / "inputs";
    const std::string model_id = t.options.value("model", "");
    ReviewInputs r;
    // Ground reactions: uploaded, or derived from a C3D's force plates by the pipeline.
    fs::path grf = inputs / "grf.mot", loads = inputs / "loads.xml";
    if (!fs::exists(grf)) grf = result_dir(t) / (t.name + "_grf.mot"), loads = result_dir(t) / (t.name + "_grf.xml");
    if (fs::exists(grf) && fs::exists(loads)) r.grf = text::read_file(grf.string()), r.loads = text::read_file(loads.string());
    // Footage trials: the markers are the capture stage's TRC, on the tag corners it added to the model.
    const bool footage = fs::is_directory(inputs / "videos");
    r.markers_file = footage ? (result_dir(t) / (t.name + ".trc")).string() : (inputs / "markers.trc").string();
    r.marker_set = footage ? (result_dir(t) / (t.name + "_tag_markers.xml")).string() : jobs_.marker_set_path(model_id);
    r.model = jobs_.model_path(model_id);
    if (const fs::path scaled = result_dir(t) / (t.name + "_scaled.osim"); fs::exists(scaled)) {
      r.model = scaled.string();
      r.marker_set.clear();
    }
    return r;
  }

  // source "ik" (default): the trial's; "gait": the reproduced gait laid on the trial's frames (those
  // its simulation covers), for the dashboard's overlay.
  void kinematics(const std::string& id, const std::string& source, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    if (source != "ik" && source != "gait") return send_error(res, 400, "bad_parameter", "source must be ik or gait", "source");
    const auto in = review_inputs(*t, &res);
    if (!in) return;
    try {
      const std::string ik_path = (result_dir(*t) / (t->name + "_ik.mot")).string();
      if (source == "gait") {
        const auto gait = std::find_if(t->stages.begin(), t->stages.end(), [](const StageRecord& s) { return s.name == "gait"; });
        const fs::path motion = result_dir(*t) / (t->name + "_gait.mot");
        if (gait == t->stages.end() || gait->state != "done" || !gait->summary.contains("reference_begin_s") || !fs::exists(motion))
          return send_error(res, 409, "not_ready", "the reproduced gait did not run for this trial", "source");
        const Storage ik = read_storage(ik_path);
        const std::vector<double> times(ik.time().data(), ik.time().data() + ik.num_rows());
        return send_json(res, 200,
                         trial_kinematics_json(in->model, in->marker_set,
                                               motion_at_times(read_storage(motion.string()), times, gait->summary["reference_begin_s"].get<double>()),
                                               text::read_file(in->markers_file), "", ""));
      }
      send_json(res, 200, trial_kinematics_json(in->model, in->marker_set, ik_path, text::read_file(in->markers_file), in->grf, in->loads));
    } catch (const std::exception& e) {
      send_error(res, 409, "not_ready", std::string("kinematics not available: ") + e.what());
    }
  }

  void cycles(const std::string& id, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    const auto in = review_inputs(*t, &res);
    if (!in) return;
    try {
      send_json(res, 200, trial_cycles_json(in->model, in->marker_set, result_dir(*t).string(), t->name, in->grf, in->loads));
    } catch (const std::exception& e) {
      send_error(res, 409, "not_ready", std::string("gait cycles not available: ") + e.what());
    }
  }

  // The self-contained HTML report: summary, stages, warnings, gait-cycle plots (when IK is done and
  // the trial holds a stride).
  void report(const std::string& id, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    json cycles = nullptr;
    if (const auto in = review_inputs(*t, nullptr)) try {
        cycles = trial_cycles_json(in->model, in->marker_set, result_dir(*t).string(), t->name, in->grf, in->loads);
      } catch (const std::exception&) {  // no full stride: the report goes without cycle plots
      }
    const auto model = store_.model(t->options.value("model", ""));
    res.set_header("Content-Disposition", "attachment; filename=\"" + t->name + "_report.html\"");
    res.set_content(trial_report_html(*t, model ? &*model : nullptr, cycles), "text/html; charset=utf-8");
  }

  void file(const std::string& id, const std::string& name, httplib::Response& res) {
    auto t = find(id, res);
    if (!t) return;
    if (!is_safe_file_name(name)) return send_error(res, 400, "bad_file_name", "unsafe file name '" + name + "'", "name");
    const fs::path p = result_dir(*t) / name;
    if (!fs::is_regular_file(p)) return send_error(res, 404, "not_found", "no result file '" + name + "'", "name");
    res.set_content(text::read_file(p.string()), name.size() > 5 && name.substr(name.size() - 5) == ".json" ? "application/json" : "text/plain");
  }
};

thread_local std::chrono::steady_clock::time_point t_request_start;

// An Accept-Encoding value without "br". Debian's cpp-httplib (0.11.4) answers any client that
// accepts Brotli with Brotli at quality 11, about 0.5 MB/s here: a 15 s trial's 18 MB kinematics
// took 38 s to send. Without "br" it uses gzip (level 6), which takes 1.2 s.
std::string without_brotli(const std::string& accept_encoding) {
  std::string kept;
  std::string_view rest = accept_encoding;
  while (!rest.empty()) {
    const std::size_t comma = std::min(rest.find(','), rest.size());
    const std::string_view token = text::trim(rest.substr(0, comma));
    rest.remove_prefix(std::min(comma + 1, rest.size()));
    if (token.empty() || text::trim(token.substr(0, token.find(';'))) == "br") continue;
    if (!kept.empty()) kept += ", ";
    kept += token;
  }
  return kept;
}

// The service without its socket: the store, the job runner (not started) and an httplib server
// with the API installed. serve() listens with it; InProcessServer feeds it requests directly.
class HttpServer : public httplib::Server {
 public:
  using httplib::Server::process_request;
};

struct ServiceCore {
  explicit ServiceCore(const ServerOptions& o)
      : o(o),
        store(prepare_data_dir(o.data_dir, o.store)),
        jobs(store, changes, o.data_dir,
             {o.workers, o.lease_s, o.heartbeat_s, store.dialect() == SqlDialect::kSqlite, ""}),
        api(o, store, changes, requests, jobs) {
    register_builtin_model();
    server.new_task_queue = [] { return new httplib::ThreadPool(64); };
    server.set_payload_max_length(o.max_upload_bytes);
    server.set_read_timeout(o.read_timeout_s, 0);
    server.set_write_timeout(o.read_timeout_s, 0);
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response&) {
      t_request_start = std::chrono::steady_clock::now();
      // httplib chooses the response's encoding from this header after routing; the request object
      // is the server's own (not const), handed to handlers as const.
      auto& headers = const_cast<httplib::Request&>(req).headers;
      if (auto it = headers.find("Accept-Encoding"); it != headers.end()) it->second = without_brotli(it->second);
      requests++;
      return httplib::Server::HandlerResponse::Unhandled;
    });
    // Every error leaves as JSON, including httplib's own (413 too large, 400 bad request, 404).
    server.set_error_handler([](const httplib::Request&, httplib::Response& res) {
      if (!res.body.empty()) return;
      const char* code = res.status == 413 ? "payload_too_large" : res.status == 404 ? "not_found" : "http_error";
      const std::string message = res.status == 413 ? "upload is larger than the server accepts"
                                  : "HTTP error " + std::to_string(res.status);
      send_error(res, res.status, code, message);
    });
    server.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
      try {
        std::rethrow_exception(ep);
      } catch (const std::exception& e) {
        send_error(res, 500, "internal_error", e.what());
      }
    });
    api.install(server);
  }

  // The folders the store and the jobs write into; returns the store's spec (default: SQLite in the data folder).
  static std::string prepare_data_dir(const std::string& data_dir, const std::string& store) {
    ensure_directory((fs::path(data_dir) / "trials").string());
    ensure_directory((fs::path(data_dir) / "models").string());
    return store.empty() ? "sqlite:" + (fs::path(data_dir) / "cpgait.sqlite").string() : store;
  }

  // cpgait's own fixture model is always there, so a first upload needs no model upload.
  void register_builtin_model() {
    const fs::path builtin = fs::path(CPGAIT_FIXTURES_DIR) / "models" / "walker.osim";
    if (store.model("walker") || !fs::exists(builtin)) return;
    ensure_directory((fs::path(o.data_dir) / "models" / "walker").string());
    fs::copy_file(builtin, fs::path(o.data_dir) / "models" / "walker" / "model.osim", fs::copy_options::overwrite_existing);
    const OsimReadResult r = read_osim(builtin.string());
    store.insert_model({"walker", "walker.osim (cpgait fixture)", now_iso8601(), r.warnings,
                        {{"bodies", r.model.bodies.size() - 1}, {"coordinates", r.model.num_coordinates()},
                         {"markers", r.model.markers.size()}, {"muscles", r.model.muscles.size()}, {"mass_kg", r.model.total_mass_kg()}}});
  }

  const ServerOptions& o;
  Store store;
  ChangeSignal changes;
  std::atomic<long> requests{0};
  JobRunner jobs;
  Api api;
  HttpServer server;
};

}  // namespace

struct InProcessServer::Impl {
  explicit Impl(const ServerOptions& o) : options(o), core(options) {}
  ServerOptions options;
  ServiceCore core;
};

InProcessServer::InProcessServer(const ServerOptions& options) : impl_(std::make_unique<Impl>(options)) {}
InProcessServer::~InProcessServer() = default;

std::string InProcessServer::handle(const std::string& raw_request) {
  httplib::detail::BufferStream stream;
  stream.write(raw_request.data(), raw_request.size());
  bool closed = false;
  impl_->core.server.process_request(stream, true, closed, nullptr);
  return stream.get_buffer().substr(raw_request.size());
}

int serve(const ServerOptions& o) {
  ServiceCore core(o);
  httplib::Server& server = core.server;
  server.set_logger([](const httplib::Request& req, const httplib::Response& res) {
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_request_start).count();
    json line = {{"event", "request"}, {"method", req.method}, {"path", req.path}, {"status", res.status}, {"ms", ms}};
    std::smatch m;
    static const std::regex trial_re(R"(/api/v1/trials/([0-9a-f]{16}))");
    if (std::regex_search(req.path, m, trial_re)) line["trial"] = m[1].str();
    log_line(line);
  });

  // httplib 0.11 listens with a backlog of 5, compiled into Debian's library: a burst of uploads
  // would see refused or retried connections. It hands us the listening socket before binding;
  // listen() again after binding raises the backlog.
  int listen_fd = -1;
  server.set_socket_options([&listen_fd](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listen_fd = sock;
  });
  const int port = o.port == 0 ? server.bind_to_any_port(o.host) : (server.bind_to_port(o.host, o.port) ? o.port : -1);
  if (port >= 0 && listen_fd >= 0) ::listen(listen_fd, 1024);
  if (port < 0) {
    std::fprintf(stderr, "error: cannot listen on %s:%d (in use?)\n", o.host.c_str(), o.port);
    return 1;
  }
  core.jobs.start();
  g_server = &server;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::printf("listening on http://%s:%d\ndashboard: http://%s:%d/  data: %s  store: %s  workers: %d%s\n", o.host.c_str(), port,
              o.host.c_str(), port, fs::absolute(o.data_dir).string().c_str(),
              core.store.dialect() == SqlDialect::kPostgres ? "postgresql" : "sqlite", o.workers, o.token.empty() ? "" : "  token required");
  std::fflush(stdout);
  server.listen_after_bind();
  g_server = nullptr;
  core.jobs.stop();
  return 0;
}

namespace {
std::atomic<bool> g_worker_stop{false};
}  // namespace

int run_worker(const WorkerOptions& o) {
  ensure_directory((fs::path(o.data_dir) / "trials").string());
  Store store(o.store, o.threads + 1);
  ChangeSignal changes;
  JobRunner jobs(store, changes, o.data_dir, {o.threads, o.lease_s, o.heartbeat_s, false, o.name});
  std::signal(SIGINT, [](int) { g_worker_stop = true; });
  std::signal(SIGTERM, [](int) { g_worker_stop = true; });
  jobs.start();
  std::printf("worker %s ready: store %s (schema %d), data %s, threads %d, lease %.1f s\n", jobs.name().c_str(),
              store.dialect() == SqlDialect::kPostgres ? "postgresql" : "sqlite", store.schema_version(),
              fs::absolute(o.data_dir).string().c_str(), o.threads, o.lease_s);
  std::fflush(stdout);
  while (!g_worker_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  jobs.stop();  // a running trial finishes its current stage check, then is left to its lease
  return 0;
}

}  // namespace cpgait::services
