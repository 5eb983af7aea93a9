#pragma once
// OpenSim's AnalyzeTool setup with its StaticOptimization, InverseDynamics and MuscleAnalysis analyses. Paths as
// written; `setup_dir` is what they are relative to.
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cpgait {

struct AnalyzeSetup {
  std::string name;
  std::string setup_dir;
  std::string model_file;
  std::vector<std::string> force_set_files;
  bool replace_force_set = false;
  std::string results_directory = ".";
  std::string coordinates_file;
  std::string states_file;  // used where no coordinates_file is given (MuscleAnalysis only)
  bool solve_for_equilibrium = false;  // solve_for_equilibrium_for_auxiliary_states
  std::string external_loads_file;
  double lowpass_cutoff_hz = -1;
  std::optional<std::pair<double, double>> time_range_s;  // initial_time, final_time
  // The StaticOptimization analysis (absent when the setup has none).
  bool has_static_optimization = false;
  int step_interval = 1;
  double activation_exponent = 2.0;
  bool use_muscle_physiology = true;
  bool use_model_force_set = true;
  // The InverseDynamics analysis (absent when the setup has none).
  bool has_inverse_dynamics = false;
  // The MuscleAnalysis (absent when the setup has none).
  bool has_muscle_analysis = false;
  int muscle_analysis_step_interval = 1;
  std::string muscle_analysis_name;  // names its output files: <tool>_<analysis>_Length.sto
  std::vector<std::string> muscle_list;  // empty: all muscles (OpenSim's "all")
  std::vector<std::string> moment_arm_coordinates;  // "all": every coordinate
  std::vector<std::string> warnings;  // analyses that are on but not run, by file and line
};

AnalyzeSetup read_analyze_setup(const std::string& path);

}  // namespace cpgait
