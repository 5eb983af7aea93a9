#pragma once
// Computed Muscle Control (Thelen, Anderson & Delp 2003; Thelen & Anderson 2006), as OpenSim's CMC
// tool with its fast optimization target. Every window [t, t + T] (T = 0.01 s):
//  1. PD task accelerations for each tracked coordinate (OpenSim's CMC_Joint):
//       qdd* = ka qdd_d(t+T) + kv (u_d(t) - u(t)) + kp (q_d(t) - q(t)).
//  2. Forces at t + T that produce exactly those accelerations on the state predicted for t + T
//     (the desired path at t + T plus the current errors; external loads at t + T; the model's
//     own passive forces, such as coordinate limits and path springs, counted), minimising
//       sum_muscles (F / F_opt)^2 + sum_actuators control^2,
//     F_opt a muscle's force at full activation with a stiff tendon (OpenSim's weighting), each
//     muscle force limited to what it can reach by t + T from its current state: the muscle's
//     activation and fibre length integrated over the window at the lowest and highest excitation
//     while its path moves to the predicted length (compliant tendons: muscles::compliant_muscle_after),
//     or its activation alone (rigid tendons).
//  3. Each muscle's excitation: the constant excitation that gives that force at t + T (Illinois
//     regula falsi; the force rises with excitation).
//  4. Forward dynamics of the muscle-driven model over the window (ROS34PW2 by default, error
//     controlled), muscle excitations held (OpenSim's step controls), actuator controls ramped.
// The run starts settle_s before the first output time so activations are in equilibrium there
// (OpenSim starts 0.03 s early as well); at the first output time q and u are reset to the desired
// values, the muscles keeping their states. External forces: measured loads (GRF) when given, else
// contact spheres, else none.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/activation/actuators.h"
#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/storage.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/progress.h"

namespace cpgait {

enum class CmcIntegrator {
  kRos34pw2,      // third-order Rosenbrock-W, the muscles' stiff parts implicit (rosenbrock_w.h): the default
  kRosenbrockW,   // ROS2 with the same W: second order
  kDormandPrince  // explicit 5(4): the reference it is checked against, ~10x more evaluations
};

struct ComputedMuscleControlOptions {
  std::optional<std::pair<double, double>> time_range_s;  // default: the desired kinematics' range
  double window_s = 0.01;           // OpenSim's cmc_time_window
  double settle_s = 0.03;           // start this much earlier (or, at the data's start, output this much later)
  double lowpass_cutoff_hz = -1;    // desired kinematics filter; negative: none (OpenSim's default)
  // Relative and absolute, per state; <= 0: the integrator's own, 2e-4 for ROS34PW2 and 1e-3 for the
  // others (their estimates are of second and first order: ROS34PW2 at 2e-4 tracks as ROS2 at 1e-3
  // on both references, at 0.71x the instructions on subject01; figures in test_cmc.cpp). Not
  // OpenSim's integrator_error_tolerance (another method and norm). Default -1.
  double integrator_tolerance = -1;
  CmcIntegrator integrator = CmcIntegrator::kRos34pw2;
  double output_interval_s = 0.001;    // states, forces and kinematics are recorded this often
  // Also re-solve the ideal actuators (residuals, reserves) every output interval at the current
  // state, muscle forces as they are, for the same task accelerations. Off: once per window, as
  // OpenSim. On subject01 it halves most tracking errors and the mtp errors (5-9 deg -> 2-3 deg),
  // with the same average residuals, but the left ankle's error grows (0.67 -> 1.16 deg) (measured).
  bool refresh_actuators = false;
  bool compliant_tendons = true;       // OpenSim's Thelen2003Muscle; false: rigid tendons
  // With contact spheres (no measured loads): put the contact set's ground under the desired
  // kinematics' feet, at their height and, on a treadmill, moving with the belt (contact.h). Off:
  // the contact file's ground.
  bool place_ground_under_feet = true;
};

struct ComputedMuscleControlSummary {
  int windows = 0;
  int windows_infeasible = 0;      // the task accelerations could not be met within the bounds
  int windows_residuals_unbounded = 0;  // met only with the residuals beyond their constraints
  long integrator_steps = 0, integrator_rejected = 0, evaluations = 0;
  double simulated_s = 0, solve_seconds = 0;
  std::string external_forces;     // "measured loads", "contact spheres" or "none"
  std::vector<std::string> warnings;
  double real_time_factor() const { return solve_seconds > 0 ? simulated_s / solve_seconds : 0; }
  std::string BriefReport() const;
};

struct ComputedMuscleControlResult {
  std::vector<std::string> coordinate_names, muscle_names, actuator_names;
  std::vector<int> residual_actuators;  // indices into actuator_names acting on the root's 6 DoF
  // Controls as OpenSim's ControlSet nodes: each window's excitations then actuator controls at the
  // window's end (muscles hold it over the window, actuators ramp to it), after a first node with
  // the values in force at the first output time. Tracking errors q_desired - q (rad, m) at each
  // window's start.
  std::vector<double> control_time_s, window_time_s;
  Eigen::MatrixXd controls, position_error;
  // Per output sample.
  std::vector<double> time_s;
  Eigen::MatrixXd q, u, activation, fiber_length_m, muscle_force_N, actuator_force;
  ComputedMuscleControlSummary summary;
  // Mean of each residual actuator's force over the output samples (OpenSim's avgResiduals).
  std::vector<std::pair<std::string, double>> average_residuals() const;
  // RMS of position_error per coordinate over windows at or after the first output time.
  Eigen::VectorXd position_error_rms() const;
};

// tasks: the CMC task set (coordinates by name); constraints: control ranges (nullptr: each
// muscle's and actuator's own range). loads or contacts may be nullptr (loads win when both given).
ComputedMuscleControlResult computed_muscle_control(const Model& model, const Storage& desired_kinematics,
                                                    const AppliedLoads* loads, const ContactSet* contacts,
                                                    const ResolvedActuators& actuators,
                                                    const std::vector<CmcJointTask>& tasks,
                                                    const ControlSetSpec* constraints,
                                                    const ComputedMuscleControlOptions& options = {},
                                                    Progress* progress = nullptr);

// OpenSim's outputs: _controls.sto, _states.sto, _Kinematics_q.sto (degrees), _pErr.sto,
// _Actuation_force.sto, and the _avgResiduals.txt text.
Storage cmc_controls_table(const ComputedMuscleControlResult& r);
Storage cmc_states_table(const ComputedMuscleControlResult& r);
Storage cmc_kinematics_q_table(const Model& model, const ComputedMuscleControlResult& r);
Storage cmc_position_error_table(const ComputedMuscleControlResult& r);
Storage cmc_actuation_force_table(const ComputedMuscleControlResult& r);
std::string cmc_average_residuals_text(const ComputedMuscleControlResult& r);

}  // namespace cpgait
