#pragma once
// OpenSim's Computed Muscle Control inputs: the CMCTool and ForwardTool setups, the CMC task set
// (CMC_Joint / rdCMC_Joint tasks: PD gains per coordinate) and control constraints (ControlSet
// XML: each control's allowed range). Paths as written; `setup_dir` is what they are relative to.
#include <optional>
#include <string>
#include <vector>

namespace cpgait {

struct CmcJointTask {
  std::string name, coordinate;
  bool on = true;
  double kp = 100, kv = 20, ka = 1, weight = 1;  // first component (a joint task has one)
  std::string file;
  int line = 0;
};
// Reads <CMC_TaskSet> / <rdCMC_TaskSet>; CMC_Point or CMC_Orientation tasks throw InputError
// (cpgait tracks coordinates only).
std::vector<CmcJointTask> read_cmc_tasks(const std::string& path);
std::vector<CmcJointTask> parse_cmc_tasks(const std::string& text, const std::string& name);  // an upload's

struct ControlBounds {
  std::string name;  // actuator name: the ControlLinear's name without ".excitation"
  double min = 0, max = 1;
  bool use_steps = true;  // piecewise constant (muscles); false: linear between nodes
  std::vector<double> node_times_s, node_values;  // x_nodes, when the file carries a control history
  // min_nodes / max_nodes: bounds that change in time (a constraints file's); none: min and max.
  std::vector<double> min_node_times_s, min_node_values, max_node_times_s, max_node_values;
  bool extrapolate = true;  // linear past the first and last nodes (OpenSim's ControlLinear, without steps)
  double min_at(double t_s) const;  // OpenSim's getControlValueMin / Max
  double max_at(double t_s) const;
};
struct ControlSetSpec {
  std::optional<ControlBounds> defaults;
  std::vector<ControlBounds> controls;
  const ControlBounds* find(const std::string& actuator) const;  // the control or the defaults
};
ControlSetSpec read_control_set(const std::string& path);
ControlSetSpec parse_control_set(const std::string& text, const std::string& name);  // an upload's

struct CmcSetup {
  std::string name, setup_dir, model_file, results_directory = ".";
  std::vector<std::string> force_set_files;
  bool replace_force_set = false;
  double initial_time_s = 0, final_time_s = 0;
  std::string external_loads_file, desired_kinematics_file, task_set_file, constraints_file;
  double lowpass_cutoff_hz = -1;
  double cmc_time_window_s = 0.01;
  bool use_fast_target = true;
  double integrator_error_tolerance = 1e-6;
};
CmcSetup read_cmc_setup(const std::string& path);

struct ForwardSetup {
  std::string name, setup_dir, model_file, results_directory = ".";
  std::vector<std::string> force_set_files;
  bool replace_force_set = false;
  double initial_time_s = 0, final_time_s = 0;
  std::string external_loads_file, controls_file, states_file;
  double integrator_error_tolerance = 1e-5;
  // CorrectionController gains (OpenSim's tracking of the states file's coordinates); unset: none.
  std::optional<double> correction_kp, correction_kv;
};
ForwardSetup read_forward_setup(const std::string& path);

}  // namespace cpgait
