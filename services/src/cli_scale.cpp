// scale: OpenSim's ScaleTool (GenericModelMaker, ModelScaler, MarkerPlacer) from its setup, as
// `cpgait scale SETUP` and `cpgait run-tool SETUP`.
#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/scale_setup.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_writer.h"
#include "cpgait/scaling/fit_scale_factors.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "cpgait/scaling/place_markers.h"
#include "cpgait/scaling/scale_model.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

// An output the setup names, in the results folder (OpenSim writes beside the setup).
std::string output_path(const std::string& out_dir, const std::string& name) {
  ensure_directory(out_dir);
  return (fs::path(out_dir) / name).string();
}

void write_static_pose(const Model& model, const Eigen::VectorXd& pose, double time_s, const std::string& path) {
  Storage s = make_storage("static pose", coordinate_names(model), {time_s}, coordinates_in_file_units(model, pose.transpose()), true);
  s.extra_header = {"", "Units are S.I. units (second, meters, Newtons, ...)", "Angles are in degrees.", ""};
  write_storage_atomic(s, path);
  std::printf("wrote %s\n", path.c_str());
}

}  // namespace

void run_scale_setup(const std::string& setup_path, const ToolOverrides& o) {
  const ScaleSetup s = read_scale_setup(setup_path);
  OsimReadOptions ro;
  ro.marker_set_file = resolve_setup_file(s.setup_dir, s.marker_set_file, setup_path, "marker_set_file");
  const OsimReadResult generic = read_osim(o.model_file(s.setup_dir, s.model_file, setup_path), ro);
  print_warnings(generic.warnings);
  const std::string out_dir = o.results.empty() ? s.setup_dir : o.results;
  const std::string name = s.name.empty() ? generic.model.name : s.name;
  const OsimWriteOptions wo{name, ""};

  Model scaled = generic.model;
  if (s.scaler_apply) {
    MarkerTrial trial;
    const bool measured = std::find(s.scaling_order.begin(), s.scaling_order.end(), "measurements") != s.scaling_order.end();
    if (measured) {
      trial = read_marker_file(resolve_setup_file(s.setup_dir, s.marker_file, setup_path, "marker_file"));
      print_warnings(trial.warnings);
    }
    const ModelScaleFactors f = model_scale_factors(generic.model, s, measured ? &trial : nullptr);
    print_warnings(f.warnings);
    for (const auto& [measurement, factor] : f.measured) std::printf("measurement '%s': scale factor %.6g\n", measurement.c_str(), factor);
    scaled = scale_model(generic.model, f.body, s.preserve_mass_distribution, s.mass_kg);
    std::printf("scaled %s: %zu bodies, %.3f kg\n", name.c_str(), scaled.bodies.size() - 1, scaled.total_mass_kg());
    if (!s.output_model_file.empty()) {
      const std::string path = output_path(out_dir, s.output_model_file);
      write_text_atomic(path, osim_document(scaled, wo));
      std::printf("wrote %s\n", path.c_str());
    }
    if (!s.output_scale_file.empty()) {
      const std::string path = output_path(out_dir, s.output_scale_file);
      write_text_atomic(path, scale_set_document(scaled, f.body));
      std::printf("wrote %s\n", path.c_str());
    }
  }
  if (!s.placer_apply) return;
  const MarkerTrial static_trial = read_marker_file(resolve_setup_file(s.setup_dir, s.placer_marker_file, setup_path, "marker_file"));
  print_warnings(static_trial.warnings);
  const MarkerPlacement p = place_markers(scaled, static_trial, s.placer_tasks, s.placer_time_range_s);
  print_warnings(p.warnings);
  std::printf("placed %d markers (RMS error at the static pose before moving them: %.2f mm)\n", p.markers_moved,
              1e3 * p.marker_rms_before_m);
  if (!s.placer_output_model_file.empty()) {
    const std::string path = output_path(out_dir, s.placer_output_model_file);
    write_text_atomic(path, osim_document(p.model, wo));
    std::printf("wrote %s\n", path.c_str());
  }
  if (!s.placer_output_motion_file.empty())
    write_static_pose(p.model, p.static_pose, p.time_s, output_path(out_dir, s.placer_output_motion_file));
  if (!s.placer_output_marker_file.empty()) {
    const std::string path = output_path(out_dir, s.placer_output_marker_file);
    write_text_atomic(path, marker_set_document(p.model));
    std::printf("wrote %s\n", path.c_str());
  }
}

// Automatic scaling: the generic model's markers fitted to the static trial (and motion trials).
struct AutoScaleArgs {
  std::string model, marker_set, static_trial, tasks, results = ".", name;
  std::vector<std::string> motion;
  std::vector<double> time;
  double mass_kg = -1;
  bool per_axis = false, no_symmetry = false;
};

void run_automatic_scaling(const AutoScaleArgs& a) {
  if (a.model.empty() || a.static_trial.empty())
    throw InputError("", 0, a.model.empty() ? "--model" : "--static", "automatic scaling needs the generic model (--model) and a static trial (--static)");
  if (a.mass_kg != -1 && !(a.mass_kg > 0)) throw InputError("", 0, "--mass", "the subject's mass must be positive (kg)");
  OsimReadOptions ro;
  ro.marker_set_file = a.marker_set;
  const OsimReadResult generic = read_osim(a.model, ro);
  print_warnings(generic.warnings);
  const MarkerTrial trial = read_marker_file(a.static_trial);
  print_warnings(trial.warnings);
  std::vector<MarkerTrial> motion;
  for (const auto& m : a.motion) motion.push_back(read_marker_file(m));
  std::vector<const MarkerTrial*> motion_ptrs;
  for (const auto& m : motion) motion_ptrs.push_back(&m);
  const IkTaskSet tasks = a.tasks.empty() ? IkTaskSet{} : read_ik_tasks(a.tasks);
  ScaleFitOptions o;
  o.per_axis = a.per_axis;
  o.symmetric = !a.no_symmetry;
  o.subject_mass_kg = a.mass_kg;
  if (a.time.size() == 2) o.static_time_range_s = std::make_pair(a.time[0], a.time[1]);
  const ScaleFit fit = fit_scale_factors(generic.model, trial, tasks, motion_ptrs, o);
  print_warnings(fit.summary.warnings);
  std::printf("%s\n", fit.summary.BriefReport().c_str());
  for (std::size_t b = 1; b < fit.factors.size(); ++b)
    std::printf("  %-16s %.4f %.4f %.4f\n", generic.model.bodies[b].name.c_str(), fit.factors[b][0], fit.factors[b][1], fit.factors[b][2]);
  const std::string name = a.name.empty() ? fs::path(a.static_trial).stem().string() : a.name;
  const std::string model_path = output_path(a.results, name + "_scaled.osim");
  write_text_atomic(model_path, osim_document(fit.model, {name, ""}));
  std::printf("wrote %s (%.3f kg)\n", model_path.c_str(), fit.model.total_mass_kg());
  const std::string scale_path = output_path(a.results, name + "_scaleSet_applied.xml");
  write_text_atomic(scale_path, scale_set_document(fit.model, fit.factors));
  std::printf("wrote %s\n", scale_path.c_str());
  write_static_pose(fit.model, fit.static_pose, o.static_time_range_s ? o.static_time_range_s->first : trial.time_s.front(),
                    output_path(a.results, name + "_static_output.mot"));
}

void add_scale_command(CLI::App& app) {
  auto* sc = app.add_subcommand("scale",
                                "Scale a generic model to a subject as OpenSim's Scale tool does, from its setup (ScaleTool .xml):\n"
                                "measurement and manual scale factors, masses to the subject's, muscles' fibre and tendon lengths,\n"
                                "then markers placed on the static trial. Writes the setup's output_model_file, output_scale_file\n"
                                "and the MarkerPlacer's model, static pose (.mot) and marker set, beside the setup or in --results.\n"
                                "Without a setup, automatic scaling: --model GENERIC --static TRIAL: per-body factors, marker offsets and\n"
                                "the static pose fitted together, then markers placed; writes <name>_scaled.osim, _scaleSet_applied.xml\n"
                                "and _static_output.mot in --results.");
  struct Args {
    std::string setup;
    ToolOverrides o;
  };
  auto a = std::make_shared<Args>();
  sc->add_option("setup", a->setup, "the ScaleTool setup .xml (without one: automatic scaling)")->check(CLI::ExistingFile);
  sc->add_option("--results", a->o.results, "write the outputs here (default: beside the setup, or the current folder)");
  sc->add_option("--model", a->o.model, "the generic .osim, instead of the setup's model_file")->check(CLI::ExistingFile);
  auto au = std::make_shared<AutoScaleArgs>();
  sc->add_option("--static", au->static_trial, "automatic: the static trial (.trc or .c3d)")->check(CLI::ExistingFile);
  sc->add_option("--marker-set", au->marker_set, "automatic: a marker-set XML replacing/adding the generic model's markers")
      ->check(CLI::ExistingFile);
  sc->add_option("--tasks", au->tasks, "automatic: marker weights (an IKTaskSet .xml or its .json); default every marker 1")
      ->check(CLI::ExistingFile);
  sc->add_option("--motion", au->motion, "automatic: motion trials whose frames (10 each) are fitted too; the markers then keep "
                                          "their fitted offsets")
      ->check(CLI::ExistingFile);
  sc->add_option("--mass", au->mass_kg, "automatic: the subject's mass (kg); masses keep their shares");
  sc->add_option("--time", au->time, "automatic: the static trial's time range averaged (s): T0 T1")->expected(2);
  sc->add_option("--name", au->name, "automatic: output names' stem and the model's name (default: the static trial's)");
  sc->add_flag("--per-axis", au->per_axis, "automatic: a factor per body axis instead of one per body");
  sc->add_flag("--no-symmetry", au->no_symmetry, "automatic: left and right bodies scaled apart");
  sc->callback([a, au] {
    if (!a->setup.empty() && au->static_trial.empty()) return run_scale_setup(a->setup, a->o);
    if (!a->setup.empty()) throw InputError(a->setup, 0, "--static", "give a setup or a static trial (automatic scaling), not both");
    au->model = a->o.model;
    if (!a->o.results.empty()) au->results = a->o.results;
    run_automatic_scaling(*au);
  });
}

}  // namespace cpgait::services
