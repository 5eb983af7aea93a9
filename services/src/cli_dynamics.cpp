// id: inverse dynamics from the command line and from OpenSim setups.
#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "cpgait/capture/analyze_setup.h"
#include "cpgait/capture/id_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

struct IdInputs {
  std::string model, coordinates, loads, grf;
  InverseDynamicsOptions options;
};

void run_id(const IdInputs& in, const std::string& out_path) {
  const OsimReadResult mr = read_osim(in.model);
  print_warnings(mr.warnings);
  const Storage coords = read_storage(in.coordinates);
  std::unique_ptr<AppliedLoads> loads;
  if (!in.loads.empty()) {
    const ExternalLoadsSpec spec = read_external_loads(in.loads);
    std::string data = in.grf;
    if (data.empty()) data = resolve_setup_file(spec.setup_dir, spec.datafile, in.loads, "datafile");
    if (data.empty()) throw InputError(in.loads, 0, "datafile", "the external loads name no data file (give --grf)");
    loads = std::make_unique<AppliedLoads>(mr.model, spec, read_storage(data));
  }
  const InverseDynamicsResult r = inverse_dynamics(mr.model, coords, loads.get(), in.options);
  print_warnings(r.summary.warnings);
  ensure_directory(fs::path(out_path).parent_path().empty() ? "." : fs::path(out_path).parent_path().string());
  write_storage_atomic(inverse_dynamics_table(mr.model, r), out_path);
  std::printf("%s%s\nwrote %s\n", r.summary.BriefReport().c_str(), loads ? " with external loads" : "", out_path.c_str());
}

// What ID needs from a setup: IdSetup (InverseDynamicsTool) and AnalyzeSetup (its
// InverseDynamics analysis) name the same fields.
template <typename Setup>
IdInputs id_inputs(const Setup& s, const std::string& setup_path, const ToolOverrides& o) {
  IdInputs in;
  in.model = o.model_file(s.setup_dir, s.model_file, setup_path);
  in.coordinates = resolve_setup_file(s.setup_dir, s.coordinates_file, setup_path, "coordinates_file");
  if (in.coordinates.empty())
    throw InputError(setup_path, 0, "coordinates_file", "inverse dynamics needs a coordinates_file (cpgait reads a states file for MuscleAnalysis only)");
  in.loads = resolve_setup_file(s.setup_dir, s.external_loads_file, setup_path, "external_loads_file");
  in.options.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  in.options.time_range_s = s.time_range_s;
  return in;
}

}  // namespace

void run_id_setup(const std::string& setup_path, const ToolOverrides& o) {
  const IdSetup s = read_id_setup(setup_path);
  const std::string dir = o.results_dir(s.setup_dir, s.results_directory);
  const std::string file = s.output_gen_force_file.empty() ? "inverse_dynamics.sto" : s.output_gen_force_file;
  run_id(id_inputs(s, setup_path, o), (fs::path(dir) / file).string());
}

void run_id_analysis(const std::string& setup_path, const ToolOverrides& o) {
  const AnalyzeSetup s = read_analyze_setup(setup_path);
  const std::string dir = o.results_dir(s.setup_dir, s.results_directory);
  run_id(id_inputs(s, setup_path, o), (fs::path(dir) / ((s.name.empty() ? "analyze" : s.name) + "_InverseDynamics.sto")).string());
}

void add_dynamics_commands(CLI::App& app) {
  auto* id = app.add_subcommand("id",
                                "Inverse dynamics (recursive Newton-Euler): generalized forces from coordinates and\n"
                                "external loads. Inputs: .osim model, coordinates .mot/.sto (angles in degrees unless the\n"
                                "file says inDegrees=no), optional OpenSim ExternalLoads .xml with its GRF .mot (N, m, N m).\n"
                                "Output: an .sto with <coordinate>_moment (N m) and <coordinate>_force (N) columns.");
  auto a = std::make_shared<IdInputs>();
  auto out = std::make_shared<std::string>();
  auto time = std::make_shared<std::vector<double>>();
  id->add_option("--model", a->model, "OpenSim model (.osim)")->required()->check(CLI::ExistingFile);
  id->add_option("--coordinates", a->coordinates, "coordinates (.mot/.sto), e.g. the IK result")
      ->required()
      ->check(CLI::ExistingFile);
  id->add_option("--loads", a->loads, "ExternalLoads .xml (which GRF columns act on which body)")->check(CLI::ExistingFile);
  id->add_option("--grf", a->grf, "GRF data .mot (default: the datafile the loads name)")->check(CLI::ExistingFile);
  id->add_option("--cutoff", a->options.lowpass_cutoff_hz, "low-pass cutoff for the coordinates, Hz (negative: none)")
      ->capture_default_str();
  id->add_option("--time", *time, "first and last time, seconds")->expected(2);
  id->add_option("-o,--output", *out, "the .sto to write")->required();
  id->callback([a, out, time] {
    if (time->size() == 2) a->options.time_range_s = std::make_pair((*time)[0], (*time)[1]);
    run_id(*a, *out);
  });
}

}  // namespace cpgait::services
