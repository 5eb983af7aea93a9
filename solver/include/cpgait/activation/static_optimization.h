#pragma once
// Static optimization as OpenSim's StaticOptimization analysis: at each frame, minimise
// sum |x_i|^p over muscle activations and actuator controls subject to
//   sum_muscles r_m F_opt,m a_m + sum_actuators G_j x_j = tau_ID(q, qd, qdd, external loads)
// and each control within [min_control, max_control]. F_opt,m is the muscle's active force along
// the tendon at full activation with a rigid tendon and the current fibre length and velocity
// (force-length-velocity on, OpenSim's default), or max isometric force with physiology off.
// As in OpenSim, muscle forces are x * F_opt (the passive force is not added).
#include <Eigen/Core>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cpgait/activation/actuators.h"
#include "cpgait/capture/storage.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/optim/dual_newton.h"
#include "cpgait/progress.h"

namespace cpgait {

struct StaticOptimizationOptions {
  double activation_exponent = 2.0;  // p
  bool use_muscle_physiology = true;
  double lowpass_cutoff_hz = -1;     // coordinates filter, as in ID; negative: none
  std::optional<std::pair<double, double>> time_range_s;
  int step_interval = 1;             // analyse every n-th sample of the coordinates, and the last one (as OpenSim)
  std::vector<double> output_times_s;  // analyse at these times instead (s), inside the data
  double equality_tolerance = 1e-9;  // relative to 1 + max generalized force: ~1e-6 N m here
};

struct StaticOptimizationSummary {
  int frames = 0;
  int frames_not_converged = 0;
  int total_iterations = 0;
  double max_equality_violation = 0;  // N m or N, over all frames and coordinates
  double solve_seconds = 0;
  std::vector<std::string> warnings;
  double frames_per_second() const { return solve_seconds > 0 ? frames / solve_seconds : 0; }
  std::string BriefReport() const;
};

struct StaticOptimizationResult {
  std::vector<double> time_s;
  std::vector<std::string> names;   // muscles, then actuators
  Eigen::MatrixXd controls;         // frames x names: activations of muscles, controls of actuators
  Eigen::MatrixXd forces;           // frames x names: N (or N m for torque actuators)
  Eigen::VectorXd equality_violation;  // per frame, max over coordinates
  StaticOptimizationSummary summary;
};

StaticOptimizationResult static_optimization(const Model& model, const Storage& coordinates, const AppliedLoads* loads,
                                             const ResolvedActuators& actuators,
                                             const StaticOptimizationOptions& options = {},
                                             Progress* progress = nullptr);

// OpenSim's outputs: <name>_StaticOptimization_activation.sto and _force.sto.
Storage static_optimization_activation_table(const StaticOptimizationResult& r);
Storage static_optimization_force_table(const StaticOptimizationResult& r);

}  // namespace cpgait
