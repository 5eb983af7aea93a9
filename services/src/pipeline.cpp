#include "pipeline.h"

#include <chrono>
#include <filesystem>

#include "cpgait/activation/static_optimization.h"
#include "cpgait/capture/external_loads.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/kinematics/gait_events.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "output_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;
using nlohmann::json;

const std::vector<std::string> kStages = {"ik", "id", "so", "cpg", "gait"};

namespace {

[[noreturn]] void bad(const std::string& source, const std::string& field, const std::string& message) {
  throw InputError(source, 0, field, message);
}

void only_keys(const json& j, const std::vector<std::string>& allowed, const std::string& source, const std::string& prefix) {
  if (!j.is_object()) bad(source, prefix.empty() ? "options" : prefix, "expected a JSON object");
  for (const auto& [k, v] : j.items())
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
      bad(source, prefix + k, "unknown option (expected one of: " + [&] {
        std::string s;
        for (const auto& a : allowed) s += (s.empty() ? "" : ", ") + a;
        return s;
      }() + ")");
}

double number(const json& j, const char* key, double fallback, const std::string& source, const std::string& field) {
  if (!j.contains(key)) return fallback;
  if (!j.at(key).is_number()) bad(source, field, "expected a number");
  return j.at(key).get<double>();
}

// Residuals on the root joint's coordinates and reserves on the others, all weak (optimal force 1),
// so static optimization is always feasible and prefers muscles.
std::vector<ActuatorSpec> default_actuators(const Model& model) {
  std::vector<ActuatorSpec> out;
  for (const Joint& j : model.joints)
    for (int c : j.coordinates) {
      ActuatorSpec a;
      a.coordinate = model.coordinates[c].name;
      a.name = a.coordinate + (j.parent_body == 0 ? "_residual" : "_reserve");
      a.optimal_force = 1.0;
      out.push_back(a);
    }
  return out;
}

class StageTimer {
 public:
  StageTimer(PipelineObserver* o, std::string stage) : o_(o), stage_(std::move(stage)), start_(std::chrono::steady_clock::now()) {
    if (o_) o_->stage_started(stage_);
  }
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  PipelineObserver* o_;
  std::string stage_;
  std::chrono::steady_clock::time_point start_;
};

// Progress of one stage, forwarded to the observer.
class StageProgress : public Progress {
 public:
  StageProgress(PipelineObserver* o, std::string stage) : o_(o), stage_(std::move(stage)) {}
  void report(double fraction, std::string_view) override {
    if (o_ && fraction - last_ >= 0.05) {
      last_ = fraction;
      o_->stage_progress(stage_, fraction);
    }
  }
  bool cancelled() const override { return o_ && o_->cancelled(); }

 private:
  PipelineObserver* o_;
  std::string stage_;
  double last_ = 0;
};

}  // namespace

bool is_safe_file_name(const std::string& n) {
  if (n.empty() || n.size() > 200 || n[0] == '.') return false;
  for (char c : n)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-')) return false;
  return true;
}

bool PipelineOptions::wants(const std::string& stage) const {
  return std::find(stages.begin(), stages.end(), stage) != stages.end();
}

PipelineOptions PipelineOptions::parse(const std::string& text, const std::string& source) {
  return from_json(text.empty() ? json::object() : parse_json_input(text, source), source);
}

PipelineOptions PipelineOptions::from_json(const json& j, const std::string& source) {
  PipelineOptions o;
  only_keys(j, {"model", "scale_muscles_from", "stages", "time_range", "ik", "id", "so", "cpg", "gait", "capture", "inputs"}, source, "");
  if (j.contains("model")) {
    if (!j["model"].is_string()) bad(source, "model", "expected a model id string");
    o.model_id = j["model"].get<std::string>();
  }
  if (j.contains("scale_muscles_from")) {
    if (!j["scale_muscles_from"].is_string()) bad(source, "scale_muscles_from", "expected a model id string");
    o.scale_muscles_from_id = j["scale_muscles_from"].get<std::string>();
  }
  if (j.contains("stages")) {
    if (!j["stages"].is_array() || j["stages"].empty()) bad(source, "stages", "expected a non-empty array of stage names");
    o.stages.clear();
    for (const auto& s : j["stages"]) {
      if (!s.is_string() || std::find(kStages.begin(), kStages.end(), s.get<std::string>()) == kStages.end())
        bad(source, "stages", "unknown stage " + s.dump() + " (stages: ik, id, so, cpg, gait)");
      o.stages.push_back(s.get<std::string>());
    }
    // A stage needs the ones before it.
    for (std::size_t k = 1; k < kStages.size(); ++k)
      if (o.wants(kStages[k]) && !o.wants(kStages[k - 1]))
        bad(source, "stages", "stage '" + kStages[k] + "' needs '" + kStages[k - 1] + "'");
  }
  if (j.contains("time_range")) {
    const auto& t = j["time_range"];
    if (!t.is_array() || t.size() != 2 || !t[0].is_number() || !t[1].is_number() || !(t[0].get<double>() <= t[1].get<double>()))
      bad(source, "time_range", "expected [first, last] in seconds with first <= last");
    o.time_range_s = std::make_pair(t[0].get<double>(), t[1].get<double>());
  }
  if (j.contains("ik")) {
    const auto& ik = j["ik"];
    only_keys(ik, {"bounds", "tasks"}, source, "ik.");
    if (ik.contains("bounds")) {
      const std::string b = ik["bounds"].is_string() ? ik["bounds"].get<std::string>() : "";
      if (b == "clamped") o.ik_bounds = IkOptions::Bounds::kClampedOnly;
      else if (b == "all") o.ik_bounds = IkOptions::Bounds::kAllRanges;
      else if (b == "none") o.ik_bounds = IkOptions::Bounds::kNone;
      else bad(source, "ik.bounds", "expected \"clamped\", \"all\" or \"none\"");
    }
    if (ik.contains("tasks")) {
      parse_ik_tasks_json(ik["tasks"].dump(), source + " (ik.tasks)");  // validates
      o.ik_tasks = ik["tasks"];
    }
  }
  if (j.contains("id")) {
    only_keys(j["id"], {"lowpass_cutoff_hz"}, source, "id.");
    o.id_cutoff_hz = number(j["id"], "lowpass_cutoff_hz", o.id_cutoff_hz, source, "id.lowpass_cutoff_hz");
  }
  if (j.contains("so")) {
    const auto& so = j["so"];
    only_keys(so, {"activation_exponent", "use_muscle_physiology", "lowpass_cutoff_hz"}, source, "so.");
    o.so_exponent = number(so, "activation_exponent", o.so_exponent, source, "so.activation_exponent");
    if (!(o.so_exponent >= 2.0)) bad(source, "so.activation_exponent", "must be at least 2");
    if (so.contains("use_muscle_physiology")) {
      if (!so["use_muscle_physiology"].is_boolean()) bad(source, "so.use_muscle_physiology", "expected true or false");
      o.so_physiology = so["use_muscle_physiology"].get<bool>();
    }
    o.so_cutoff_hz = number(so, "lowpass_cutoff_hz", o.so_cutoff_hz, source, "so.lowpass_cutoff_hz");
  }
  if (j.contains("gait")) {
    const auto& g = j["gait"];
    only_keys(g, {"duration_s", "residuals"}, source, "gait.");
    o.gait_duration_s = number(g, "duration_s", o.gait_duration_s, source, "gait.duration_s");
    if (g.contains("duration_s") && !(o.gait_duration_s > 0 && o.gait_duration_s <= 30)) bad(source, "gait.duration_s", "expected 0 to 30 s");
    if (g.contains("residuals")) {
      if (!g["residuals"].is_boolean()) bad(source, "gait.residuals", "expected true or false");
      o.gait_residuals = g["residuals"].get<bool>();
    }
  }
  if (j.contains("cpg")) {
    const auto& c = j["cpg"];
    only_keys(c, {"pairs", "pattern_units", "foot"}, source, "cpg.");
    o.cpg_pairs = static_cast<int>(number(c, "pairs", o.cpg_pairs, source, "cpg.pairs"));
    if (o.cpg_pairs < 1 || o.cpg_pairs > 6) bad(source, "cpg.pairs", "expected 1 to 6 oscillator pairs");
    o.cpg_pattern_units = static_cast<int>(number(c, "pattern_units", o.cpg_pattern_units, source, "cpg.pattern_units"));
    if (o.cpg_pattern_units < 0 || o.cpg_pattern_units > 2) bad(source, "cpg.pattern_units", "expected 0, 1 or 2");
    if (c.contains("foot")) {
      if (!c["foot"].is_string()) bad(source, "cpg.foot", "expected a body name");
      o.cpg_foot = c["foot"].get<std::string>();
    }
  }
  if (j.contains("capture")) {
    const auto& c = j["capture"];
    only_keys(c, {"max_reprojection_px", "gap_fill_s", "single_view", "sync", "decimate"}, source, "capture.");
    o.capture.triangulation.max_reprojection_error_px =
        number(c, "max_reprojection_px", o.capture.triangulation.max_reprojection_error_px, source, "capture.max_reprojection_px");
    if (!(o.capture.triangulation.max_reprojection_error_px > 0)) bad(source, "capture.max_reprojection_px", "must be positive");
    o.capture.max_gap_fill_s = number(c, "gap_fill_s", o.capture.max_gap_fill_s, source, "capture.gap_fill_s");
    if (!(o.capture.max_gap_fill_s >= 0 && o.capture.max_gap_fill_s <= 1)) bad(source, "capture.gap_fill_s", "expected 0 to 1 s");
    if (c.contains("single_view")) {
      if (!c["single_view"].is_boolean()) bad(source, "capture.single_view", "expected true or false");
      o.capture.single_view_pose = c["single_view"].get<bool>();
    }
    if (c.contains("sync")) {
      const std::string sync = c["sync"].is_string() ? c["sync"].get<std::string>() : "";
      if (sync != "index" && sync != "time") bad(source, "capture.sync", "expected \"index\" or \"time\"");
      o.capture.sync = sync == "time" ? video::CaptureOptions::Sync::kTime : video::CaptureOptions::Sync::kIndex;
    }
    const double decimate = number(c, "decimate", o.capture.detector.quad_decimate, source, "capture.decimate");
    if (!(decimate >= 1 && decimate <= 8)) bad(source, "capture.decimate", "expected 1 to 8");
    o.capture.detector.quad_decimate = static_cast<float>(decimate);
  }
  if (j.contains("inputs")) {
    if (!j["inputs"].is_object()) bad(source, "inputs", "expected an object of file paths");
    o.inputs = j["inputs"];
  }
  return o;
}

json PipelineOptions::to_json() const {
  json j;
  if (!model_id.empty()) j["model"] = model_id;
  if (!scale_muscles_from_id.empty()) j["scale_muscles_from"] = scale_muscles_from_id;
  j["stages"] = stages;
  if (time_range_s) j["time_range"] = {time_range_s->first, time_range_s->second};
  j["ik"]["bounds"] = ik_bounds == IkOptions::Bounds::kClampedOnly ? "clamped" : ik_bounds == IkOptions::Bounds::kAllRanges ? "all" : "none";
  if (ik_tasks) j["ik"]["tasks"] = *ik_tasks;
  j["id"]["lowpass_cutoff_hz"] = id_cutoff_hz;
  j["so"] = {{"activation_exponent", so_exponent}, {"use_muscle_physiology", so_physiology}, {"lowpass_cutoff_hz", so_cutoff_hz}};
  j["cpg"] = {{"pairs", cpg_pairs}, {"pattern_units", cpg_pattern_units}};
  j["gait"] = {{"residuals", gait_residuals}};
  if (gait_duration_s > 0) j["gait"]["duration_s"] = gait_duration_s;
  if (!cpg_foot.empty()) j["cpg"]["foot"] = cpg_foot;
  j["capture"] = {{"max_reprojection_px", capture.triangulation.max_reprojection_error_px},
                  {"gap_fill_s", capture.max_gap_fill_s},
                  {"single_view", capture.single_view_pose},
                  {"sync", capture.sync == video::CaptureOptions::Sync::kTime ? "time" : "index"},
                  {"decimate", capture.detector.quad_decimate}};
  if (!inputs.empty()) j["inputs"] = inputs;
  return j;
}

namespace {
OsimReadResult read_trial_model(const TrialInputs& in) {
  OsimReadOptions o;
  o.marker_set_file = in.marker_set_path;
  OsimReadResult r = read_osim(in.model_path, o);
  if (!in.generic_model_path.empty()) r.model = scale_muscle_parameters(r.model, read_osim(in.generic_model_path).model);
  return r;
}
}  // namespace

void load_footage_inputs(const std::string& inputs_dir, TrialInputs& in) {
  const fs::path dir(inputs_dir);
  if (!fs::is_directory(dir / "videos")) return;
  std::vector<fs::path> videos;
  for (const auto& e : fs::directory_iterator(dir / "videos"))
    if (e.is_regular_file()) videos.push_back(e.path());
  std::sort(videos.begin(), videos.end());
  for (const fs::path& v : videos) in.videos.push_back(v.stem().string() + "=" + v.string());
  for (const char* ext : {".json", ".yml", ".yaml", ".xml"})
    if (fs::exists(dir / (std::string("calibration") + ext))) in.calibration_path = (dir / (std::string("calibration") + ext)).string();
  in.tags_path = (dir / "tags.json").string();
}

void validate_inputs(const TrialInputs& in, const PipelineOptions& options) {
  Model model = read_trial_model(in).model;
  if (in.has_footage()) {
    const video::CameraRig rig = video::read_calibration(in.calibration_path);
    const video::TagSet tags = video::read_tag_set(in.tags_path);
    model = video::with_tag_markers(model, tags, in.tags_path);
    for (const auto& [camera, path] : video::match_videos_to_cameras(rig, in.videos)) video::probe_video(path);
    return;  // the markers exist only after the capture stage
  }
  const MarkerTrial trial = parse_trc(in.markers, in.markers_name);
  if (!in.grf.empty() || !in.loads.empty()) {
    if (in.grf.empty()) throw InputError(in.loads_name, 0, "grf", "external loads were given without their GRF data (.mot)");
    if (in.loads.empty()) throw InputError(in.grf_name, 0, "loads", "GRF data were given without the ExternalLoads XML naming the bodies");
    AppliedLoads(model, parse_external_loads(in.loads, in.loads_name), parse_storage(in.grf, in.grf_name));
  }
  IkOptions io;
  io.time_range_s = options.time_range_s;
  make_ik_targets(model, trial, options.ik_tasks ? parse_ik_tasks_json(options.ik_tasks->dump(), "options (ik.tasks)") : IkTaskSet{}, io);
  if (options.time_range_s) {
    bool any = false;
    for (double t : trial.time_s) any |= t >= options.time_range_s->first - 1e-9 && t <= options.time_range_s->second + 1e-9;
    if (!any) throw InputError("options", 0, "time_range", "no frame of the trial lies in the requested time range");
  }
}

PipelineResult run_pipeline(const TrialInputs& in, const PipelineOptions& options, const std::string& out_dir,
                            PipelineObserver* observer) {
  PipelineResult result;
  ensure_directory(out_dir);
  auto write = [&](const Storage& s, const std::string& file) {
    write_storage_atomic(s, (fs::path(out_dir) / file).string());
    result.files.push_back(file);
  };
  const OsimReadResult mr = read_trial_model(in);
  Model model = mr.model;
  MarkerTrial trial;
  // Capture: AprilTag footage -> virtual markers (the tag corners), which the model gains as markers.
  if (in.has_footage()) {
    StageTimer timer(observer, "capture");
    StageProgress progress(observer, "capture");
    const video::CameraRig rig = video::read_calibration(in.calibration_path);
    const video::TagSet tags = video::read_tag_set(in.tags_path);
    model = video::with_tag_markers(model, tags, in.tags_path);
    video::CaptureResult r = video::capture_markers(rig, tags, in.videos, options.capture, &progress);
    r.markers.name = in.name + ".trc";
    write_text_atomic((fs::path(out_dir) / (in.name + ".trc")).string(), format_trc(r.markers, "mm"));
    result.files.push_back(in.name + ".trc");
    write(video::capture_quality_table(r), in.name + "_capture_quality.sto");
    write_text_atomic((fs::path(out_dir) / (in.name + "_tag_markers.xml")).string(), video::format_marker_set_xml(tags));
    result.files.push_back(in.name + "_tag_markers.xml");
    const auto& cs = r.summary;
    const json summary = {{"frames", cs.num_frames},
                          {"cameras", cs.cameras},
                          {"frames_per_second", cs.detect_seconds > 0 ? cs.num_frames * static_cast<double>(cs.cameras.size()) / cs.detect_seconds : 0.0},
                          {"corners_triangulated", cs.corners_triangulated},
                          {"corners_single_view", cs.corners_single_view},
                          {"corners_gap_filled", cs.corners_filled},
                          {"corners_missing", cs.corners_missing},
                          {"views_rejected", cs.views_rejected},
                          {"median_reprojection_px", cs.median_reprojection_px},
                          {"warnings", cs.warnings}};
    result.summary["capture"] = summary;
    trial = std::move(r.markers);
    if (observer) observer->stage_finished("capture", timer.seconds(), summary);
  } else {
    trial = parse_trc(in.markers, in.markers_name);
  }
  std::unique_ptr<AppliedLoads> loads;
  if (!in.grf.empty())
    loads = std::make_unique<AppliedLoads>(model, parse_external_loads(in.loads, in.loads_name), parse_storage(in.grf, in.grf_name));

  // IK
  Storage coordinates;
  Eigen::MatrixXd ik_q;
  std::vector<double> ik_time;
  StaticOptimizationResult so_result;
  if (options.wants("ik")) {
    StageTimer timer(observer, "ik");
    StageProgress progress(observer, "ik");
    IkOptions io;
    io.bounds = options.ik_bounds;
    io.time_range_s = options.time_range_s;
    const IkTaskSet tasks = options.ik_tasks ? parse_ik_tasks_json(options.ik_tasks->dump(), "options (ik.tasks)") : IkTaskSet{};
    const IkResult r = inverse_kinematics(model, trial, tasks, io, nullptr, &progress);
    ik_q = r.q;
    ik_time = r.time_s;
    coordinates = ik_coordinates_table(model, r);
    write(coordinates, in.name + "_ik.mot");
    write(ik_marker_errors_table(r), in.name + "_ik_marker_errors.sto");
    const json summary = {{"frames", r.summary.frames},
                          {"frames_per_second", r.summary.frames_per_second()},
                          {"marker_rms_mean_m", r.summary.mean_marker_rms_m},
                          {"marker_rms_max_m", r.summary.max_marker_rms_m},
                          {"marker_error_max_m", r.summary.max_marker_error_m},
                          {"frames_not_converged", r.summary.frames_not_converged},
                          {"warnings", r.summary.warnings}};
    result.summary["ik"] = summary;
    if (observer) observer->stage_finished("ik", timer.seconds(), summary);
  }
  // ID
  if (options.wants("id")) {
    StageTimer timer(observer, "id");
    StageProgress progress(observer, "id");
    InverseDynamicsOptions o;
    o.lowpass_cutoff_hz = options.id_cutoff_hz;
    const InverseDynamicsResult r = inverse_dynamics(model, coordinates, loads.get(), o, &progress);
    write(inverse_dynamics_table(model, r), in.name + "_id.sto");
    const json summary = {{"frames", r.summary.frames},
                          {"frames_per_second", r.summary.frames_per_second()},
                          {"external_loads", loads != nullptr},
                          {"warnings", r.summary.warnings}};
    result.summary["id"] = summary;
    if (observer) observer->stage_finished("id", timer.seconds(), summary);
  }
  // SO
  if (options.wants("so")) {
    StageTimer timer(observer, "so");
    StageProgress progress(observer, "so");
    StaticOptimizationOptions o;
    o.activation_exponent = options.so_exponent;
    o.use_muscle_physiology = options.so_physiology;
    o.lowpass_cutoff_hz = options.so_cutoff_hz;
    const ResolvedActuators actuators(model, default_actuators(model));
    so_result = static_optimization(model, coordinates, loads.get(), actuators, o, &progress);
    const StaticOptimizationResult& r = so_result;
    write(static_optimization_activation_table(r), in.name + "_StaticOptimization_activation.sto");
    write(static_optimization_force_table(r), in.name + "_StaticOptimization_force.sto");
    std::vector<std::string> warnings = r.summary.warnings;
    if (std::string w = unscaled_muscles_warning(model); !w.empty()) warnings.push_back(std::move(w));
    const json summary = {{"frames", r.summary.frames},
                          {"frames_per_second", r.summary.frames_per_second()},
                          {"max_equality_violation", r.summary.max_equality_violation},
                          {"frames_not_converged", r.summary.frames_not_converged},
                          {"warnings", warnings}};
    result.summary["so"] = summary;
    if (observer) observer->stage_finished("so", timer.seconds(), summary);
  }
  // CPG: fitted to the SO activations over the gait cycles of one foot.
  std::optional<CpgModel> fitted_cpg;
  std::vector<double> cpg_strikes;
  if (options.wants("cpg")) {
    StageTimer timer(observer, "cpg");
    json summary;
    std::vector<double> strikes;
    std::string source;
    if (!in.grf.empty()) {
      const Storage grf = parse_storage(in.grf, in.grf_name);
      for (int c = 1; c < grf.num_columns() && strikes.empty(); ++c)
        if (grf.labels[static_cast<std::size_t>(c)] == "ground_force_vy") {
          strikes = contact_onsets(grf.time(), grf.data.col(c));
          source = "GRF ground_force_vy (20 N threshold)";
        }
    }
    if (strikes.size() < 2) {
      const std::string foot = !options.cpg_foot.empty() ? options.cpg_foot : model.body_index("calcn_r") >= 0 ? "calcn_r" : "foot_r";
      strikes = heel_strikes_zeni(model, ik_time, ik_q, foot);
      source = "kinematics (Zeni 2008), " + foot;
    }
    const int nm = static_cast<int>(model.muscles.size());
    std::vector<std::string> names(so_result.names.begin(), so_result.names.begin() + nm);
    int cycles = 0;
    const double cycle_s = mean_cycle_duration(so_result.time_s, strikes, &cycles);
    summary = {{"heel_strikes_s", strikes}, {"heel_strike_source", source}, {"cycles", cycles}};
    if (cycles == 0 || nm == 0) {
      // Not an error of the trial: IK, ID and SO stand; the stage says why it fitted nothing.
      summary["not_fitted"] = nm == 0 ? "the model has no muscles" : "no full gait cycle (two heel strikes of one foot) inside the trial";
    } else {
      CpgFitOptions fo;
      fo.pairs = options.cpg_pairs;
      fo.pattern_units = options.cpg_pattern_units;
      const Eigen::MatrixXd cycle = cycle_average(so_result.time_s, so_result.controls.leftCols(nm), strikes, fo.phase_samples);
      const CpgFitResult fit = fit_cpg(cycle, cycle_s, names, fo);
      fitted_cpg = fit.model;
      cpg_strikes = strikes;
      write_text_atomic((fs::path(out_dir) / (in.name + "_cpg.json")).string(), fit.model.to_json().dump(2) + "\n");
      result.files.push_back(in.name + "_cpg.json");
      std::vector<double> phase_time;
      for (int k = 0; k < cycle.rows(); ++k) phase_time.push_back(cycle_s * k / static_cast<double>(cycle.rows()));
      write(make_storage("cycle-averaged SO activations", names, phase_time, fit.target, false), in.name + "_cpg_target.sto");
      write(make_storage("CPG excitations, fitted", names, phase_time, fit.fitted, false), in.name + "_cpg_fitted.sto");
      const CpgRun run = run_cpg(fit.model, cycle_s, cycle_s / static_cast<double>(cycle.rows()));
      std::vector<std::string> neurons;
      const int rhythm = 2 * fo.pairs;
      for (int i = 0; i < fit.model.network.size(); ++i)
        neurons.push_back(i < rhythm ? "rhythm" + std::to_string(i) : "pattern" + std::to_string(i - rhythm));
      write(make_storage("CPG neuron outputs over one cycle", neurons, run.time_s, run.neurons, false), in.name + "_cpg_neurons.sto");
      json r2 = json::object();
      for (std::size_t k = 0; k < names.size(); ++k) r2[names[k]] = fit.summary.r_squared[static_cast<Eigen::Index>(k)];
      summary["cycle_s"] = cycle_s;
      summary["mean_r_squared_active"] = fit.summary.mean_r_squared_active;
      summary["active_muscles"] = fit.summary.active_muscles;
      summary["neurons"] = fit.model.network.size();
      summary["r_squared"] = r2;
    }
    result.summary["cpg"] = summary;
    if (observer) observer->stage_finished("cpg", timer.seconds(), summary);
  }
  // The reproduced gait: the fitted CPG drives the muscles on contact spheres.
  if (options.wants("gait")) {
    StageTimer timer(observer, "gait");
    json summary;
    ContactSet feet = default_foot_contacts(model);
    const double cycle_s = fitted_cpg ? fitted_cpg->cycle_s : 0;
    double start = -1;
    for (double s : cpg_strikes)
      if (fitted_cpg && !ik_time.empty() && s + fitted_cpg->phase_at_start * cycle_s >= ik_time.front()) {
        start = s;
        break;
      }
    // The simulation begins at the heel strike's phase, or earlier when the trial would end first.
    const double available = ik_time.empty() ? 0 : ik_time.back() - ik_time.front();
    const double duration = options.gait_duration_s > 0 ? options.gait_duration_s : std::min(2 * cycle_s, available);
    if (!fitted_cpg) {
      summary["not_run"] = "no CPG was fitted in this run (see the cpg stage)";
    } else if (feet.spheres.empty()) {
      summary["not_run"] = "the model has no calcn_/toes_ or foot_ bodies for contact spheres";
    } else if (start < 0 || available < 0.5 * cycle_s) {
      summary["not_run"] = "the trial is shorter than half a gait cycle, or has no usable heel strike";
    } else {
      const Storage ik = make_storage("ik", coordinate_names(model), ik_time, ik_q, false);
      const FootSphereFit fit = fit_foot_spheres_to_trial(model, feet, ik_time, ik_q);
      ReproducedGaitOptions go;
      go.start_time_s = start;
      go.duration_s = duration;
      go.pelvis_residuals = options.gait_residuals;
      StageProgress progress(observer, "gait");
      const ReproducedGaitResult g = reproduce_gait(model, *fitted_cpg, ik, feet, go, &progress);
      write(reproduced_gait_motion_table(model, g), in.name + "_gait.mot");
      write(reproduced_gait_residual_table(g), in.name + "_gait_residuals.sto");
      write(reproduced_gait_contact_table(g), in.name + "_gait_contact_forces.sto");
      summary = reproduced_gait_metrics(model, g);
      json radius = json::object();
      for (std::size_t s = 0; s < feet.spheres.size(); ++s) radius[feet.spheres[s].name] = fit.radius_change_m[s] * 1000;
      summary["foot_fit"] = {{"depth_mm", fit.depth_m * 1000}, {"radius_change_mm", radius}, {"warnings", fit.warnings}};
      summary["belt_velocity_m_s"] = {feet.ground_velocity_m_s.x(), feet.ground_velocity_m_s.y(), feet.ground_velocity_m_s.z()};
      write_text_atomic((fs::path(out_dir) / (in.name + "_gait.json")).string(), summary.dump(2) + "\n");
      result.files.push_back(in.name + "_gait.json");
    }
    result.summary["gait"] = summary;
    if (observer) observer->stage_finished("gait", timer.seconds(), summary);
  }
  write_text_atomic((fs::path(out_dir) / "job.json").string(), options.to_json().dump(2) + "\n");
  result.files.push_back("job.json");
  return result;
}

}  // namespace cpgait::services
