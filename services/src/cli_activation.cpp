// so: static optimization from the command line and from OpenSim AnalyzeTool setups.
#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "cpgait/activation/static_optimization.h"
#include "cpgait/capture/analyze_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

struct SoInputs {
  std::string model, coordinates, loads, grf, out_dir, name = "static_optimization";
  std::vector<std::string> actuator_files;
  bool use_model_actuators = true;
  bool replace_force_set = false;
  StaticOptimizationOptions options;
};

void run_so(const SoInputs& in) {
  OsimReadResult mr = read_osim(in.model);
  print_warnings(mr.warnings);
  std::vector<ActuatorSpec> specs;
  if (in.replace_force_set) {
    mr.model.muscles.clear();  // OpenSim replaces the whole force set, muscles included
  } else if (in.use_model_actuators) {
    specs = read_actuators(in.model);
  }
  for (const auto& f : in.actuator_files) {
    auto more = read_actuators(f);
    specs.insert(specs.end(), more.begin(), more.end());
  }
  const ResolvedActuators actuators(mr.model, specs);
  std::unique_ptr<AppliedLoads> loads;
  if (!in.loads.empty()) {
    const ExternalLoadsSpec spec = read_external_loads(in.loads);
    const std::string data = !in.grf.empty() ? in.grf : resolve_setup_file(spec.setup_dir, spec.datafile, in.loads, "datafile");
    loads = std::make_unique<AppliedLoads>(mr.model, spec, read_storage(data));
  }
  const StaticOptimizationResult r =
      static_optimization(mr.model, read_storage(in.coordinates), loads.get(), actuators, in.options);
  print_warnings(r.summary.warnings);
  ensure_directory(in.out_dir);
  const std::string a = (fs::path(in.out_dir) / (in.name + "_StaticOptimization_activation.sto")).string();
  const std::string f = (fs::path(in.out_dir) / (in.name + "_StaticOptimization_force.sto")).string();
  write_storage_atomic(static_optimization_activation_table(r), a);
  write_storage_atomic(static_optimization_force_table(r), f);
  std::printf("%s%s\nwrote %s\nwrote %s\n", r.summary.BriefReport().c_str(), loads ? " with external loads" : "", a.c_str(),
              f.c_str());
}

}  // namespace

void run_so_setup(const std::string& setup_path, const std::string& results_override) {
  const AnalyzeSetup s = read_analyze_setup(setup_path);
  if (!s.has_static_optimization)
    throw InputError(setup_path, 0, "AnalysisSet", "the AnalyzeTool setup has no StaticOptimization analysis that is on");
  SoInputs in;
  in.model = resolve_setup_file(s.setup_dir, s.model_file, setup_path, "model_file");
  in.coordinates = resolve_setup_file(s.setup_dir, s.coordinates_file, setup_path, "coordinates_file");
  in.loads = resolve_setup_file(s.setup_dir, s.external_loads_file, setup_path, "external_loads_file");
  for (const auto& f : s.force_set_files) in.actuator_files.push_back(resolve_setup_file(s.setup_dir, f, setup_path, "force_set_files"));
  in.use_model_actuators = s.use_model_force_set;
  in.replace_force_set = s.replace_force_set;
  in.options.activation_exponent = s.activation_exponent;
  in.options.use_muscle_physiology = s.use_muscle_physiology;
  in.options.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  in.options.time_range_s = s.time_range_s;
  in.options.step_interval = s.step_interval;
  in.out_dir = !results_override.empty() ? results_override : (fs::path(s.setup_dir) / s.results_directory).string();
  in.name = s.name.empty() ? "static_optimization" : s.name;
  run_so(in);
}

void add_activation_commands(CLI::App& app) {
  auto* so = app.add_subcommand(
      "so",
      "Static optimization: muscle activations and actuator controls that reproduce the inverse-dynamics\n"
      "generalized forces at each frame, minimising sum of control^p. Inputs: .osim model (muscles),\n"
      "coordinates .mot/.sto (degrees unless inDegrees=no), optional ExternalLoads .xml with its GRF .mot,\n"
      "actuator ForceSet .xml files (residuals, reserves). Outputs in DIR: <name>_StaticOptimization_activation.sto\n"
      "(activations 0-1 and actuator controls) and <name>_StaticOptimization_force.sto (N, or N m for torques).");
  auto a = std::make_shared<SoInputs>();
  auto time = std::make_shared<std::vector<double>>();
  auto no_physiology = std::make_shared<bool>(false);
  so->add_option("--model", a->model, "OpenSim model (.osim)")->required()->check(CLI::ExistingFile);
  so->add_option("--coordinates", a->coordinates, "coordinates (.mot/.sto), e.g. the IK result")->required()->check(CLI::ExistingFile);
  so->add_option("--loads", a->loads, "ExternalLoads .xml")->check(CLI::ExistingFile);
  so->add_option("--grf", a->grf, "GRF data .mot (default: the datafile the loads name)")->check(CLI::ExistingFile);
  so->add_option("--actuators", a->actuator_files, "actuator ForceSet .xml files (repeatable)")->check(CLI::ExistingFile);
  so->add_option("--cutoff", a->options.lowpass_cutoff_hz, "low-pass cutoff for the coordinates, Hz (negative: none)")
      ->capture_default_str();
  so->add_option("--time", *time, "first and last time, seconds")->expected(2);
  so->add_option("--exponent", a->options.activation_exponent, "activation exponent p (>= 2)")
      ->check(CLI::Range(2.0, 100.0))
      ->capture_default_str();
  so->add_option("--step", a->options.step_interval, "analyse every n-th sample")->capture_default_str();
  so->add_flag("--no-physiology", *no_physiology, "use max isometric force instead of force-length-velocity");
  so->add_option("--name", a->name, "output file prefix")->capture_default_str();
  so->add_option("-o,--output", a->out_dir, "output folder")->required();
  so->callback([a, time, no_physiology] {
    if (time->size() == 2) a->options.time_range_s = std::make_pair((*time)[0], (*time)[1]);
    a->options.use_muscle_physiology = !*no_physiology;
    run_so(*a);
  });
}

}  // namespace cpgait::services
