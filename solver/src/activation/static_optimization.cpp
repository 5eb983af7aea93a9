#include "cpgait/activation/static_optimization.h"

#include <chrono>
#include <cstdio>

#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/dynamics/rnea.h"
#include "cpgait/muscles/muscle_path.h"
#include "cpgait/muscles/muscle_model.h"

namespace cpgait {

StaticOptimizationResult static_optimization(const Model& model, const Storage& coordinates, const AppliedLoads* loads,
                                             const ResolvedActuators& actuators, const StaticOptimizationOptions& options,
                                             Progress* progress) {
  StaticOptimizationResult result;
  InverseDynamicsOptions id_options;
  id_options.lowpass_cutoff_hz = options.lowpass_cutoff_hz;
  id_options.time_range_s = options.time_range_s;
  id_options.output_times_s = options.output_times_s;
  const CoordinateTrajectories k = coordinate_trajectories(model, coordinates, id_options);
  result.summary.warnings = k.warnings;

  const int nq = model.num_coordinates(), nm = static_cast<int>(model.muscles.size()), na = actuators.size();
  const int n = nm + na;
  for (const auto& mu : model.muscles) result.names.push_back(mu.name);
  for (int i = 0; i < na; ++i) result.names.push_back(actuators.spec(i).name);
  // OpenSim's AnalyzeTool records the first and the last frame of the range and, between them, every
  // frame whose row in the coordinates file is a multiple of the step interval.
  const int step = std::max(1, options.step_interval), nk = static_cast<int>(k.time_s.size());
  int first_row = 0;
  if (options.output_times_s.empty())
    while (first_row < coordinates.num_rows() && coordinates.data(first_row, 0) < k.time_s[0] - 1e-9) ++first_row;
  std::vector<int> frames;
  for (int i = 0; i < nk; ++i)
    if (i == 0 || i == nk - 1 || (first_row + i) % step == 0) frames.push_back(i);
  const int nf = static_cast<int>(frames.size());
  result.controls.resize(nf, n);
  result.forces.resize(nf, n);
  result.equality_violation.resize(nf);

  // Bounds: OpenSim uses each actuator's control range.
  Eigen::VectorXd lo(n), hi(n);
  for (int m = 0; m < nm; ++m) {
    lo[m] = model.muscles[m].min_control;
    hi[m] = model.muscles[m].max_control;
  }
  for (int i = 0; i < na; ++i) {
    lo[nm + i] = actuators.spec(i).min_control;
    hi[nm + i] = actuators.spec(i).max_control;
  }

  const bool coupled = has_coordinate_constraints(model);
  const std::vector<int> free = free_coordinates(model);
  Eigen::MatrixXd G, A_free;
  Eigen::VectorXd tau_free;
  KinematicsWorkspace<double> ws(model);
  MotionSubspace S(model);
  DynamicsWorkspace dws(model);
  MusclePathGeometry geometry(model);
  std::vector<Vector6d> external(loads ? model.bodies.size() : 0);
  Eigen::MatrixXd A(nq, n);
  Eigen::VectorXd q(nq), qd(nq), qdd(nq), tau(nq), passive(nq), f_opt(n), lambda, x;
  DualNewtonOptions qp;
  qp.exponent = options.activation_exponent;
  qp.tolerance = options.equality_tolerance;
  const auto start = std::chrono::steady_clock::now();
  for (int fi = 0; fi < nf; ++fi) {
    if (progress && progress->cancelled()) throw std::runtime_error("static optimization cancelled");
    const int i = frames[fi];
    q = k.q.row(i).transpose();
    qd = k.qd.row(i).transpose();
    qdd = k.qdd.row(i).transpose();
    if (coupled) {
      // The state assembled on its constraints, as OpenSim's: locked coordinates held, coupled ones
      // on their functions.
      assemble_coordinate_constraints(model, q.data(), qd.data(), qdd.data());
    }
    forward_kinematics(model, q.data(), ws);
    motion_subspace(model, q.data(), ws, S);
    if (loads) loads->wrenches_at(k.time_s[i], ws, external);
    rnea(model, q.data(), qd.data(), qdd.data(), external, dws, tau.data());
    // What the actuators must add to the model's passive forces (OpenSim's SO keeps them applied).
    passive.setZero();
    add_passive_generalized_forces(model, q.data(), qd.data(), ws, S, passive.data());
    tau -= passive;
    muscle_path_geometry(model, q.data(), qd.data(), ws, S, geometry);
    for (int m = 0; m < nm; ++m) {
      const Muscle& mu = model.muscles[m];
      f_opt[m] = options.use_muscle_physiology
                     ? muscles::inextensible_tendon_active_force(mu, 1.0, geometry.length_m[m], geometry.lengthening_speed_m_s[m])
                     : mu.max_isometric_force_N;
      A.col(m) = geometry.moment_arm_m.row(m).transpose() * f_opt[m];
    }
    actuators.generalized_forces(model, q.data(), ws, S, A.rightCols(na));
    for (int j = 0; j < na; ++j) f_opt[nm + j] = actuators.spec(j).optimal_force;
    if (coupled) {
      // Moment balance on the free coordinates only: G^T (A x - tau) = 0.
      coupler_velocity_map(model, q.data(), free, G);
      A_free.noalias() = G.transpose() * A;
      tau_free.noalias() = G.transpose() * tau;
    }
    const DualNewtonSummary s = minimize_power_sum(coupled ? A_free : A, coupled ? tau_free : tau, lo, hi, qp, lambda, x);
    result.summary.total_iterations += s.iterations;
    if (!s.converged) ++result.summary.frames_not_converged;
    result.equality_violation[fi] = s.equality_residual;
    result.time_s.push_back(k.time_s[i]);
    result.controls.row(fi) = x.transpose();
    result.forces.row(fi) = (x.array() * f_opt.array()).matrix().transpose();
    if (progress) progress->report(double(fi + 1) / nf, "static optimization");
  }
  result.summary.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.summary.frames = nf;
  result.summary.max_equality_violation = nf ? result.equality_violation.maxCoeff() : 0;
  if (result.summary.frames_not_converged)
    result.summary.warnings.push_back(std::to_string(result.summary.frames_not_converged) +
                                      " frames could not meet the generalized forces within the actuators' bounds "
                                      "(add reserve actuators or widen their ranges)");
  return result;
}

std::string StaticOptimizationSummary::BriefReport() const {
  char buf[300];
  std::snprintf(buf, sizeof buf,
                "SO: %d frames in %.3f s (%.0f frames/s), %d dual Newton iterations, %d frames not converged, largest "
                "equality violation %.2e",
                frames, solve_seconds, frames_per_second(), total_iterations, frames_not_converged, max_equality_violation);
  return buf;
}

Storage static_optimization_activation_table(const StaticOptimizationResult& r) {
  return make_storage("Static Optimization", r.names, r.time_s, r.controls, false);
}
Storage static_optimization_force_table(const StaticOptimizationResult& r) {
  return make_storage("Static Optimization", r.names, r.time_s, r.forces, false);
}

}  // namespace cpgait
