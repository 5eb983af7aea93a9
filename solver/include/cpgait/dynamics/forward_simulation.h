#pragma once
// OpenSim's Forward tool: the muscle-driven model integrated from an initial state under given
// controls (e.g. CMC's excitations), with measured loads or contact spheres, optionally with
// OpenSim's CorrectionController (PD generalized forces toward desired coordinates).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "cpgait/activation/actuators.h"
#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/progress.h"

namespace cpgait {

// Controls over time, one column per muscle then actuator (the system's order): piecewise constant
// (use_steps, the value of the node at or after t, as OpenSim's ControlLinear) or linear.
struct ControlHistory {
  std::vector<double> time_s;
  Eigen::MatrixXd values;       // times x (muscles + actuators)
  std::vector<bool> use_steps;  // per column
  void at(double t, Eigen::VectorXd& out) const;
};
// From CMC's _controls.sto (columns "<name>.excitation") or an OpenSim ControlSet XML with nodes.
// Controls not in the file are zero (muscles: their minimum control) and listed in `missing`.
ControlHistory control_history_from_table(const Model& model, const ResolvedActuators& actuators, const Storage& table,
                                          std::vector<std::string>* missing = nullptr);
ControlHistory control_history_from_control_set(const Model& model, const ResolvedActuators& actuators,
                                                const ControlSetSpec& set, const std::string& file,
                                                std::vector<std::string>* missing = nullptr);

struct ForwardSimulationOptions {
  double t0_s = 0, t1_s = 1;
  bool compliant_tendons = true;
  double integrator_tolerance = 1e-3;  // ROS2, as CMC (computed_muscle_control.h)
  double output_interval_s = 0.001;
  // CorrectionController: tau_c = kp (q_d - q) + kv (u_d - u) (N m per rad) toward `desired`.
  std::optional<double> correction_kp, correction_kv;
};

struct ForwardSimulationResult {
  std::vector<std::string> coordinate_names, muscle_names, actuator_names, contact_names;
  std::vector<double> time_s;
  Eigen::MatrixXd q, u, activation, fiber_length_m, muscle_force_N, actuator_force;
  Eigen::MatrixXd contact_force_N;  // times x 3 per sphere (ground frame)
  long integrator_steps = 0, evaluations = 0;
  double solve_seconds = 0;
  std::string external_forces;
  std::vector<std::string> warnings;
  std::string BriefReport() const;
};

// x0: the initial state, laid out as MuscleDrivenSystem's (q, u, activations, fibre lengths).
// desired: coordinates for the correction controller (required when its gains are set).
ForwardSimulationResult forward_simulation(const Model& model, const ResolvedActuators& actuators,
                                           const AppliedLoads* loads, const ContactSet* contacts,
                                           const ControlHistory& controls, const Eigen::VectorXd& x0,
                                           const ForwardSimulationOptions& options, const Storage* desired = nullptr,
                                           Progress* progress = nullptr);

// The initial state from a states table (CMC's _states.sto, or OpenSim's): the row at or before t
// (as OpenSim); columns by name (q, q_u, <muscle>.activation, <muscle>.fiber_length); coordinates in
// degrees when the table says so. Missing fibre lengths: tendon equilibrium.
Eigen::VectorXd initial_state_from_table(const Model& model, const Storage& states, double t_s, bool compliant_tendons,
                                         std::vector<std::string>* warnings = nullptr);

Storage forward_states_table(const ForwardSimulationResult& r);
Storage forward_kinematics_q_table(const Model& model, const ForwardSimulationResult& r);
Storage forward_actuation_force_table(const ForwardSimulationResult& r);
Storage forward_contact_force_table(const ForwardSimulationResult& r);  // empty without spheres

}  // namespace cpgait
