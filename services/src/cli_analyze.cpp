// AnalyzeTool setups: StaticOptimization (cli_activation.cpp), InverseDynamics (cli_dynamics.cpp) and
// MuscleAnalysis, written as OpenSim writes them.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include "commands.h"
#include "cpgait/capture/analyze_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_analysis.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;
namespace {

void run_muscle_analysis_setup(const std::string& setup_path, const AnalyzeSetup& s, const ToolOverrides& o) {
  const std::string model_path = o.model_file(s.setup_dir, s.model_file, setup_path);
  const OsimReadResult mr = read_osim(model_path);
  print_warnings(mr.warnings);
  const Model& model = mr.model;
  InverseDynamicsOptions ko;
  ko.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  ko.time_range_s = s.time_range_s;
  // A states file holds the coordinates under their own names (and speeds, activations and fibre
  // lengths beside them); OpenSim takes the coordinates file when both are given.
  const bool from_states = s.coordinates_file.empty();
  const std::string data_path = from_states ? resolve_setup_file(s.setup_dir, s.states_file, setup_path, "states_file")
                                            : resolve_setup_file(s.setup_dir, s.coordinates_file, setup_path, "coordinates_file");
  const Storage data = read_storage(data_path);
  const CoordinateTrajectories k = coordinate_trajectories(model, data, ko);
  print_warnings(k.warnings);
  MuscleAnalysisOptions options;
  options.step_interval = s.muscle_analysis_step_interval;
  // Fibre lengths: each muscle's isometric equilibrium at the states' activations, as OpenSim's
  // solve_for_equilibrium_for_auxiliary_states sets them.
  Eigen::MatrixXd activation;
  if (from_states && s.solve_for_equilibrium) {
    activation.resize(k.time_s.size(), model.muscles.size());
    const Eigen::VectorXd t = data.time();
    for (std::size_t m = 0; m < model.muscles.size(); ++m) {
      const std::string& name = model.muscles[m].name;
      int col = data.column(name + ".activation");
      if (col < 0) col = data.column("/forceset/" + name + "/activation");
      if (col < 0) throw InputError(data_path, 0, name + ".activation", "the states file has no activation for muscle '" + name + "'");
      for (std::size_t i = 0; i < k.time_s.size(); ++i) {
        const Eigen::Index row = std::lower_bound(t.data(), t.data() + t.size(), k.time_s[i] - 1e-9) - t.data();
        activation(i, m) = data.data(std::min<Eigen::Index>(row, t.size() - 1), col);
      }
    }
    options.activation = &activation;
  }
  if (s.moment_arm_coordinates.size() == 1 && s.moment_arm_coordinates[0] == "all") {
    for (const auto& c : model.coordinates) options.moment_arm_coordinates.push_back(c.name);
  } else {
    options.moment_arm_coordinates = s.moment_arm_coordinates;
  }
  std::vector<int> muscles;
  for (const auto& name : s.muscle_list) {
    const int found = model.muscle_index(name);
    if (found < 0) throw InputError(setup_path, 0, "muscle_list", "the model has no muscle '" + name + "'");
    muscles.push_back(found);
  }
  if (s.muscle_list.empty())
    for (std::size_t m = 0; m < model.muscles.size(); ++m) muscles.push_back(static_cast<int>(m));
  MuscleAnalysisResult r;
  try {
    r = muscle_analysis(model, k, options);
  } catch (const std::invalid_argument& e) {
    throw InputError(setup_path, 0, "moment_arm_coordinate_list", e.what());
  }
  const std::string dir = o.results_dir(s.setup_dir, s.results_directory);
  ensure_directory(dir);
  const std::string prefix =
      (fs::path(dir) / ((s.name.empty() ? "analyze" : s.name) + "_" + s.muscle_analysis_name + "_")).string();
  std::vector<std::string> labels;
  for (int m : muscles) labels.push_back(model.muscles[m].name);
  auto write = [&](const Eigen::MatrixXd& all, const std::string& what) {
    Eigen::MatrixXd v(all.rows(), muscles.size());
    for (std::size_t j = 0; j < muscles.size(); ++j) v.col(j) = all.col(muscles[j]);
    write_storage_atomic(make_storage(what, labels, r.time_s, v), prefix + what + ".sto");
    std::printf("wrote %s%s.sto\n", prefix.c_str(), what.c_str());
  };
  std::printf("%s\n", r.summary.BriefReport().c_str());
  write(r.length_m, "Length");
  write(r.lengthening_speed_m_s, "LengtheningSpeed");
  if (r.fiber_length_m.size()) write(r.fiber_length_m, "FiberLength");
  for (std::size_t c = 0; c < options.moment_arm_coordinates.size(); ++c)
    write(r.moment_arm_m[c], "MomentArm_" + options.moment_arm_coordinates[c]);
}

}  // namespace

void run_analyze_setup(const std::string& setup_path, const ToolOverrides& o) {
  const AnalyzeSetup s = read_analyze_setup(setup_path);
  for (const auto& w : s.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!s.has_static_optimization && !s.has_muscle_analysis && !s.has_inverse_dynamics)
    throw InputError(setup_path, 0, "AnalysisSet",
                     "the AnalyzeTool setup has no analysis cpgait runs that is on (StaticOptimization, InverseDynamics, MuscleAnalysis)");
  if (s.has_inverse_dynamics) run_id_analysis(setup_path, o);
  if (s.has_static_optimization) run_so_setup(setup_path, o);
  if (s.has_muscle_analysis) run_muscle_analysis_setup(setup_path, s, o);
}

}  // namespace cpgait::services
