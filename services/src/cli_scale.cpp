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

void write_static_pose(const Model& model, const MarkerPlacement& p, const std::string& path) {
  Storage s = make_storage("static pose", coordinate_names(model), {p.time_s},
                           coordinates_in_file_units(model, p.static_pose.transpose()), true);
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
  if (!s.placer_output_motion_file.empty()) write_static_pose(p.model, p, output_path(out_dir, s.placer_output_motion_file));
  if (!s.placer_output_marker_file.empty()) {
    const std::string path = output_path(out_dir, s.placer_output_marker_file);
    write_text_atomic(path, marker_set_document(p.model));
    std::printf("wrote %s\n", path.c_str());
  }
}

void add_scale_command(CLI::App& app) {
  auto* sc = app.add_subcommand("scale",
                                "Scale a generic model to a subject as OpenSim's Scale tool does, from its setup (ScaleTool .xml):\n"
                                "measurement and manual scale factors, masses to the subject's, muscles' fibre and tendon lengths,\n"
                                "then markers placed on the static trial. Writes the setup's output_model_file, output_scale_file\n"
                                "and the MarkerPlacer's model, static pose (.mot) and marker set, beside the setup or in --results.");
  struct Args {
    std::string setup;
    ToolOverrides o;
  };
  auto a = std::make_shared<Args>();
  sc->add_option("setup", a->setup, "the ScaleTool setup .xml")->required()->check(CLI::ExistingFile);
  sc->add_option("--results", a->o.results, "write the outputs here instead of beside the setup");
  sc->add_option("--model", a->o.model, "the generic .osim, instead of the setup's model_file")->check(CLI::ExistingFile);
  sc->callback([a] { run_scale_setup(a->setup, a->o); });
}

}  // namespace cpgait::services
