#include "cpgait/activation/computed_muscle_control.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/dormand_prince.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/passive_generalized_forces.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/fiber_equilibrium.h"
#include "cpgait/muscles/muscle_model.h"
#include "cpgait/optim/dual_newton.h"

namespace cpgait {

namespace {

bool is_residual(const Model& model, const ActuatorSpec& spec) {
  const Joint* root = nullptr;
  for (const auto& j : model.joints)
    if (j.parent_body == 0) {
      root = &j;
      break;
    }
  if (!root) return false;
  if (spec.kind == ActuatorSpec::Kind::kCoordinate) {
    const int c = model.coordinate_index(spec.coordinate);
    return c >= 0 && model.coordinates[c].joint == static_cast<int>(root - model.joints.data());
  }
  if (spec.kind == ActuatorSpec::Kind::kPoint) return model.body_index(spec.body) == root->child_body;
  return model.body_index(spec.body_a) == root->child_body || model.body_index(spec.body_b) == root->child_body;
}

}  // namespace

ComputedMuscleControlResult computed_muscle_control(const Model& model, const Storage& desired, const AppliedLoads* loads,
                                                    const ContactSet* contacts, const ResolvedActuators& actuators,
                                                    const std::vector<CmcJointTask>& tasks,
                                                    const ControlSetSpec* constraints,
                                                    const ComputedMuscleControlOptions& options, Progress* progress) {
  const auto clock_start = std::chrono::steady_clock::now();
  ComputedMuscleControlResult r;
  const int nq = model.num_coordinates(), nm = static_cast<int>(model.muscles.size()), na = actuators.size();
  const int nx = nm + na;
  r.coordinate_names = coordinate_names(model);
  for (const auto& m : model.muscles) r.muscle_names.push_back(m.name);
  for (int j = 0; j < na; ++j) {
    r.actuator_names.push_back(actuators.spec(j).name);
    if (is_residual(model, actuators.spec(j))) r.residual_actuators.push_back(j);
  }

  InverseDynamicsOptions ko;
  ko.lowpass_cutoff_hz = options.lowpass_cutoff_hz;
  const CoordinateTrajectories traj = coordinate_trajectories(model, desired, ko);
  r.summary.warnings = traj.warnings;
  const double data_t0 = traj.time_s.front(), data_t1 = traj.time_s.back();
  const double T = options.window_s;
  const double t_first = options.time_range_s ? options.time_range_s->first : data_t0;
  const double t_last = std::min(options.time_range_s ? options.time_range_s->second : data_t1, data_t1);  // windows end by here
  const double t_begin = std::max(t_first - options.settle_s, data_t0);
  const double t_out = std::max(t_first, t_begin + options.settle_s);
  if (!(t_last >= t_out + 2 * T - 1e-9))
    throw InputError(desired.name, 0, "time_range",
                     "CMC needs at least two windows of desired kinematics after the settling time (" +
                         std::to_string(t_out) + " s to " + std::to_string(t_last) + " s)");
  if (t_out > t_first + 1e-9)
    r.summary.warnings.push_back("the desired kinematics start at " + std::to_string(data_t0) +
                                 " s: results start after the " + std::to_string(options.settle_s) + " s settling time, at " +
                                 std::to_string(t_out) + " s");

  // Tasks -> tracked coordinates and gains.
  std::vector<int> tracked;
  Eigen::VectorXd kp = Eigen::VectorXd::Zero(nq), kv = kp, ka = kp;
  for (const auto& t : tasks) {
    if (!t.on) continue;
    const int c = model.coordinate_index(t.coordinate);
    if (c < 0) throw InputError(t.file, t.line, "coordinate", "model " + model.name + " has no coordinate " + t.coordinate);
    if (std::find(tracked.begin(), tracked.end(), c) != tracked.end()) continue;
    if (model.coordinates[c].locked ||
        std::any_of(model.couplers.begin(), model.couplers.end(), [&](const CoordinateCoupler& k) { return k.dependent == c; })) {
      r.summary.warnings.push_back("task " + t.coordinate + ": the coordinate is locked or coupled; it is not tracked");
      continue;
    }
    tracked.push_back(c);
    kp[c] = t.kp;
    kv[c] = t.kv;
    ka[c] = t.ka;
  }
  if (tracked.empty()) throw InputError(tasks.empty() ? desired.name : tasks.front().file, 0, "tasks", "no task is on");
  std::sort(tracked.begin(), tracked.end());
  // With couplers the accelerations live on the free coordinates: a = G a_free + c.
  const bool coupled = has_coordinate_constraints(model);
  const bool all_tracked = static_cast<int>(tracked.size()) == nq && !coupled;
  std::vector<int> free_index(nq, -1);
  {
    const std::vector<int> free = free_coordinates(model);
    for (std::size_t j = 0; j < free.size(); ++j) free_index[free[j]] = static_cast<int>(j);
  }

  // Control ranges: the constraints file's (at each window's start, as OpenSim evaluates its
  // min_nodes and max_nodes), within an actuator's own range; a muscle's replace its own.
  Eigen::VectorXd u_min(nx), u_max(nx);
  std::vector<bool> steps(nx, true);
  std::vector<const ControlBounds*> bounds(nx, nullptr);
  for (int m = 0; m < nm; ++m) bounds[m] = constraints ? constraints->find(model.muscles[m].name) : nullptr;
  for (int j = 0; j < na; ++j) {
    steps[nm + j] = false;
    // Only a control named in the file constrains an actuator: the defaults are written for muscles.
    const ControlBounds* b = constraints ? constraints->find(actuators.spec(j).name) : nullptr;
    if (b && constraints->defaults && b == &*constraints->defaults) b = nullptr;
    if (b) steps[nm + j] = b->use_steps;
    bounds[nm + j] = b;
  }
  auto control_ranges_at = [&](double time) {
    for (int m = 0; m < nm; ++m) {
      const ControlBounds* b = bounds[m];
      u_min[m] = b ? b->min_at(time) : model.muscles[m].min_control;
      u_max[m] = std::max(u_min[m], b ? b->max_at(time) : model.muscles[m].max_control);
    }
    for (int j = 0; j < na; ++j) {
      const ControlBounds* b = bounds[nm + j];
      u_min[nm + j] = std::max(actuators.spec(j).min_control, b ? b->min_at(time) : -std::numeric_limits<double>::infinity());
      u_max[nm + j] = std::max(u_min[nm + j], std::min(actuators.spec(j).max_control, b ? b->max_at(time) : std::numeric_limits<double>::infinity()));
    }
  };
  control_ranges_at(t_begin);

  // Contact spheres without measured loads: the ground is placed under the recorded feet, so that
  // the lowest sphere over the trial presses in as far as half the body weight presses one sphere.
  ContactSet ground;
  if (!loads && contacts) {
    ground = *contacts;
    if (options.place_ground_under_feet && !ground.spheres.empty()) {
      std::vector<int> rows;
      for (int k = 0; k < static_cast<int>(traj.time_s.size()); ++k)
        if (traj.time_s[k] >= t_begin - 1e-9 && traj.time_s[k] <= t_last + 1e-9) rows.push_back(k);
      const Eigen::MatrixXd q_rows = traj.q(rows, Eigen::all);
      std::vector<double> t_rows;
      for (int k : rows) t_rows.push_back(traj.time_s[k]);
      place_ground_under_feet(model, ground, t_rows, q_rows);
      char buf[220];
      std::snprintf(buf, sizeof buf,
                    "contact spheres: the ground placed under the desired kinematics' feet, at y = %.4f m, moving at "
                    "(%.2f, %.2f, %.2f) m/s",
                    ground.ground_height_m, ground.ground_velocity_m_s.x(), ground.ground_velocity_m_s.y(),
                    ground.ground_velocity_m_s.z());
      r.summary.warnings.emplace_back(buf);
    }
  }
  MuscleDrivenSystem sys;
  sys.model = &model;
  sys.actuators = na ? &actuators : nullptr;
  sys.loads = loads;
  sys.contacts = loads || !contacts ? nullptr : &ground;
  sys.compliant_tendons = options.compliant_tendons;
  r.summary.external_forces = loads ? "measured loads" : (sys.contacts ? "contact spheres" : "none");
  // ws holds the evaluation at the current state, ws_solve the one at the predicted state where the
  // forces are solved: the integration's first step reuses the former.
  MuscleDrivenWorkspace ws(sys), ws_solve(sys);
  auto& fd = ws.fd;

  // State.
  // Zeroed: the first derivative evaluation reads the fibre lengths before they are set (its muscle
  // forces are not used, but an uninitialised NaN there crashed a curve lookup).
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), xdot(sys.state_size()), x_pred(sys.state_size()),
                  xdot_solve(sys.state_size());
  const Eigen::VectorXd no_excitation = Eigen::VectorXd::Zero(nm), no_controls = Eigen::VectorXd::Zero(na);
  Eigen::VectorXd qd_f(nq), ud_f(nq), ad_f(nq), qd_i(nq), ud_i(nq), ad_i(nq);
  trajectories_at(traj, t_begin, qd_i, ud_i, ad_i);
  x.head(nq) = qd_i;
  x.segment(nq, nq) = ud_i;
  if (coupled) assemble_coordinate_constraints(model, x.data(), x.data() + nq);
  for (int m = 0; m < nm; ++m) x[sys.activation_index(m)] = std::max(u_min[m], 0.02);

  Eigen::VectorXd excitation = Eigen::VectorXd::Zero(nm), control_prev = Eigen::VectorXd::Zero(na), control_new(na), control_now(na);
  Eigen::MatrixXd A(nq, nx), Minv;
  Eigen::VectorXd b(nq), lo(nx), hi(nx), sol, lambda, f_opt(nm), f_pass(nm), a_lo(nm), a_hi(nm), qdd_des(nq), passive(nq);
  // Rigid tendons: fibre length and velocity from the path at the predicted state, where the forces
  // are solved. Compliant tendons: the path length now and at the window's end.
  Eigen::VectorXd path_length(nm), path_speed(nm), path_start(nm), path_end(nm);
  std::vector<muscles::PredictorStart> predictor_start(nm);
  bool use_fiber_state = false;  // false: rigid-tendon fibres from the path (also the first solve)
  // The activation whose active force (plus passive) is sol[m] * f_opt[m], within [a_min, a_max].
  auto activation_for_solution = [&](int m, double a_min, double a_max) {
    const Muscle& mu = model.muscles[m];
    const double target = sol[m] * f_opt[m] - f_pass[m];
    const double L = path_length[m], V = path_speed[m];
    double lo_a = a_min, hi_a = a_max;
    if (muscles::rigid_tendon_active_force(mu, lo_a, L, V) >= target) return lo_a;
    if (muscles::rigid_tendon_active_force(mu, hi_a, L, V) <= target) return hi_a;
    for (int i = 0; i < 50 && hi_a - lo_a > 1e-9; ++i) {
      const double mid = 0.5 * (lo_a + hi_a);
      (muscles::rigid_tendon_active_force(mu, mid, L, V) < target ? lo_a : hi_a) = mid;
    }
    return 0.5 * (lo_a + hi_a);
  };
  DualNewtonOptions qp;
  qp.tolerance = 1e-9;
  qp.exact_line_search = true;  // each window warm-starts from the last one's multipliers

  // Solves the force distribution for the accelerations qdd_des at state y and time t (OpenSim
  // evaluates it at the window's end, on the predicted state); activation limits from a_lo/a_hi.
  // Returns whether the accelerations were met.
  auto solve_forces = [&](double t, const Eigen::VectorXd& y) {
    MuscleDrivenWorkspace& w = ws_solve;
    // Kinematics, mass matrix, bias (gravity, Coriolis, external loads), path geometry and actuator
    // columns from one derivative evaluation; its own muscle and actuator forces are not used.
    muscle_driven_derivatives(sys, t, y, no_excitation, no_controls, w, xdot_solve);
    for (int m = 0; m < nm; ++m) {
      const Muscle& mu = model.muscles[m];
      if (use_fiber_state) {
        // Compliant tendons, as OpenSim's CMC: each muscle's state integrated over the window with
        // its path moving to the predicted length, at the lowest and highest excitation.
        path_end[m] = w.geometry.length_m[m];
        f_opt[m] = std::max(muscles::rigid_tendon_active_force(mu, 1.0, w.geometry.length_m[m], w.geometry.lengthening_speed_m_s[m]),
                            1e-3 * mu.max_isometric_force_N);
        f_pass[m] = 0;
        const double a0 = x[sys.activation_index(m)], lm0 = x[sys.fiber_length_index(m)];
        const double f_lo = muscles::compliant_muscle_after(mu, a0, lm0, path_start[m], path_end[m], u_min[m], T, &predictor_start[m]).force_N;
        const double f_hi = muscles::compliant_muscle_after(mu, a0, lm0, path_start[m], path_end[m], u_max[m], T, &predictor_start[m]).force_N;
        lo[m] = std::min(f_lo, f_hi) / f_opt[m];
        hi[m] = std::max(f_lo, f_hi) / f_opt[m];
        A.col(m) = w.geometry.moment_arm_m.row(m).transpose() * f_opt[m];
        continue;
      }
      const double L = path_length[m] = w.geometry.length_m[m], V = path_speed[m] = w.geometry.lengthening_speed_m_s[m];
      const RigidTendonForces full = muscles::rigid_tendon_forces(mu, 1.0, L, V);
      f_opt[m] = std::max(full.active_N, 1e-3 * mu.max_isometric_force_N);
      f_pass[m] = full.passive_N;
      A.col(m) = w.geometry.moment_arm_m.row(m).transpose() * f_opt[m];
      // Thelen's force-velocity curve scales with activation, so the force is not linear in it: the
      // bounds are the forces at the reachable activations themselves (Millard's is linear; the same
      // code serves both).
      // A muscle cannot push: where fibre damping makes the passive part negative (Millard's, while
      // shortening), the total is held at zero, as the dynamics hold it.
      lo[m] = std::max(0.0, muscles::rigid_tendon_active_force(mu, a_lo[m], L, V) + f_pass[m]) / f_opt[m];
      hi[m] = std::max(0.0, muscles::rigid_tendon_active_force(mu, a_hi[m], L, V) + f_pass[m]) / f_opt[m];
    }
    A.rightCols(na) = w.actuator_columns;
    lo.tail(na) = u_min.tail(na);
    hi.tail(na) = u_max.tail(na);
    // M qdd = A x + tau_passive - bias  with  bias = C + G - J^T f_ext: the model's own passive
    // forces (coordinate limits, springs, path springs) carry their share before the actuators.
    const double* qy = coupled ? w.x_coupled.data() : y.data();
    passive.setZero();
    add_passive_generalized_forces(model, qy, qy + nq, w.fd.kinematics, w.fd.S, passive.data());
    const Eigen::VectorXd bias = w.fd.bias - passive;
    DualNewtonSummary s;
    if (all_tracked) {
      b = w.fd.M * qdd_des + bias;
      s = minimize_power_sum(A, b, lo, hi, qp, lambda, sol);
      if (!s.converged && !r.residual_actuators.empty()) {
        // Out of reach within the constraints (typically residuals too weak for a model on contact
        // spheres): the residual actuators' bounds are lifted for this window, and counted.
        for (int j : r.residual_actuators) {
          lo[nm + j] = -std::numeric_limits<double>::infinity();
          hi[nm + j] = std::numeric_limits<double>::infinity();
        }
        lambda.resize(0);
        s = minimize_power_sum(A, b, lo, hi, qp, lambda, sol);
        if (s.converged) ++r.summary.windows_residuals_unbounded;
      }
    } else {
      const int nt = static_cast<int>(tracked.size());
      Eigen::MatrixXd At(nt, nx);
      Eigen::VectorXd bt(nt);
      if (coupled) {
        // Free accelerations: (G^T M G) a_free = G^T (A x - bias - M c), G and c at this state (the
        // derivative evaluation above left them in the workspace).
        const Eigen::MatrixXd Mr = w.G.transpose() * w.fd.M * w.G;
        const Eigen::LLT<Eigen::MatrixXd> llt(Mr);
        const Eigen::MatrixXd MA = llt.solve(w.G.transpose() * A);
        const Eigen::VectorXd Mb = llt.solve(w.G.transpose() * (bias + w.fd.M * w.c));
        for (int i = 0; i < nt; ++i) {
          At.row(i) = MA.row(free_index[tracked[i]]);
          bt[i] = qdd_des[tracked[i]] + Mb[free_index[tracked[i]]];
        }
      } else {
        Minv = w.fd.llt.solve(Eigen::MatrixXd::Identity(nq, nq));
        const Eigen::MatrixXd MA = Minv * A;
        const Eigen::VectorXd Mb = Minv * bias;
        for (int i = 0; i < nt; ++i) {
          At.row(i) = MA.row(tracked[i]);
          bt[i] = qdd_des[tracked[i]] + Mb[tracked[i]];
        }
      }
      s = minimize_power_sum(At, bt, lo, hi, qp, lambda, sol);
    }
    return s.converged;
  };

  // Compliant tendons: fibre lengths in equilibrium with the current activations and path.
  auto set_equilibrium_fibers = [&](double t) {
    if (!sys.compliant_tendons) return;
    excitation.setZero();
    control_now.setZero();
    muscle_driven_derivatives(sys, t, x, excitation, control_now, ws, xdot);
    for (int m = 0; m < nm; ++m)
      x[sys.fiber_length_index(m)] = muscles::compliant_equilibrium_fiber_length(
          model.muscles[m], x[sys.activation_index(m)], ws.geometry.length_m[m], ws.geometry.lengthening_speed_m_s[m]);
  };

  // Initial activations: the force distribution at the first instant with the full control range
  // (no activation-dynamics limit), so the run does not start from an arbitrary state.
  {
    trajectories_at(traj, t_begin, qd_f, ud_f, ad_f);
    qdd_des = ad_f;
    for (int m = 0; m < nm; ++m) {
      a_lo[m] = u_min[m];
      a_hi[m] = u_max[m];
    }
    solve_forces(t_begin, x);
    const bool initial_forces_feasible = r.summary.windows_residuals_unbounded == 0;
    r.summary.windows_residuals_unbounded = 0;  // the initial distribution is not a window
    for (int m = 0; m < nm; ++m) x[sys.activation_index(m)] = activation_for_solution(m, u_min[m], u_max[m]);
    set_equilibrium_fibers(t_begin);
    if (sys.compliant_tendons && initial_forces_feasible) {
      // Compliant tendons: the activation whose equilibrium fibre carries the solved force (the
      // rigid-tendon estimate does not: the stretched tendon shortens the fibre). Not where the first
      // instant needed the residuals beyond their range: those forces are no state the muscles hold.
      for (int m = 0; m < nm; ++m) {
        const Muscle& mu = model.muscles[m];
        if (muscles::has_rigid_tendon(mu)) continue;
        const double target = sol[m] * f_opt[m], L = ws_solve.geometry.length_m[m], V = ws_solve.geometry.lengthening_speed_m_s[m];
        auto fiber_at = [&](double a) { return muscles::compliant_equilibrium_fiber_length(mu, a, L, V); };
        // The force rises with activation: the shortfall falls.
        auto shortfall = [&](double a) { return target - muscles::compliant_tendon_fiber(mu, a, L, fiber_at(a)).force_N; };
        x[sys.activation_index(m)] = falling_root(shortfall, u_min[m], u_max[m], 1e-9);
        x[sys.fiber_length_index(m)] = fiber_at(x[sys.activation_index(m)]);
      }
    }
    control_prev = sol.tail(na);
  }

  DormandPrinceOptions io;
  const double tolerance = options.integrator_tolerance > 0 ? options.integrator_tolerance
                           : options.integrator == CmcIntegrator::kRos34pw2 ? 2e-4
                                                                            : 1e-3;
  io.relative_tolerance = io.absolute_tolerance = tolerance;
  io.max_step_s = T;
  RosenbrockOptions ro;
  ro.relative_tolerance = ro.absolute_tolerance = tolerance;
  ro.max_step_s = T;
  MuscleDrivenJacobian jac;
  const double dt_out = options.output_interval_s;
  std::vector<Eigen::VectorXd> rec_x;
  std::vector<Eigen::VectorXd> rec_fm, rec_fa;
  std::vector<Eigen::VectorXd> rec_controls, rec_perr;

  const int n_windows = static_cast<int>(std::floor((t_last - t_begin) / T + 1e-9));
  bool reset_done = t_out <= t_begin + 1e-12;
  double t = t_begin;
  // Whether ws holds the evaluation at (t, x) with this window's excitations and controls (xdot its
  // derivative): the window's first record and integration step then need none of their own.
  bool start_fresh = false;
  const bool step_controls = std::any_of(steps.begin() + nm, steps.end(), [](bool b) { return b; });
  // Evaluations that neither form the Jacobian nor feed the window's solve skip the moment-arm
  // matrix (MuscleGeometry::kLengthsAndSpeeds): the integrator's stages and the recording.
  auto stage_derivatives = [&](double time, const Eigen::VectorXd& y, Eigen::VectorXd& dy) {
    muscle_driven_derivatives(sys, time, y, excitation, control_now, ws, dy, MuscleGeometry::kLengthsAndSpeeds);
  };
  // Records between integration steps take their muscle forces from the step's two ends (linear in
  // time, as their states), once the evaluation that begins the next step has them at its end:
  // pending holds those records (index, share of the step's end). An evaluation per record was a
  // sixth of all evaluations.
  std::vector<std::pair<std::size_t, double>> pending;
  Eigen::VectorXd force_at_step_start = Eigen::VectorXd::Zero(nm);
  auto muscle_forces_at_x = [&](const Eigen::VectorXd& force) {  // ws's evaluation is at x
    for (const auto& [i, share] : pending) rec_fm[i] = (1.0 - share) * force_at_step_start + share * force;
    pending.clear();
    force_at_step_start = force;
  };
  auto record = [&](double time, const Eigen::VectorXd& state) {  // state: x
    // Forces at the recorded state: one evaluation with the controls in force at that time.
    if (!start_fresh) stage_derivatives(time, state, xdot);
    muscle_forces_at_x(ws.muscle_force_N);
    r.time_s.push_back(time);
    rec_x.push_back(state);
    rec_fm.push_back(ws.muscle_force_N);
    rec_fa.push_back(ws.actuator_force);
  };
  for (int w = 0; w < n_windows; ++w) {
    if (progress && progress->cancelled()) throw std::runtime_error("CMC cancelled");
    if (!reset_done && t >= t_out - 1e-9) {
      // OpenSim's reset after the settling time: kinematics back on the desired path.
      trajectories_at(traj, t, qd_i, ud_i, ad_i);
      x.head(nq) = qd_i;
      x.segment(nq, nq) = ud_i;
      if (coupled) assemble_coordinate_constraints(model, x.data(), x.data() + nq);
      // The muscles keep their states, as OpenSim's CMCTool keeps its initial-state computation's: a
      // fibre re-equilibrated here jumps in force (gait10dof18musc's soleus with Thelen muscles:
      // 630 -> 1370 N at once), and at 5 ms windows the stiff ankle never settled from it.
      reset_done = true;
    }
    const double tf = t + T;
    trajectories_at(traj, tf, qd_f, ud_f, ad_f);
    trajectories_at(traj, t, qd_i, ud_i, ad_i);
    // OpenSim's CMC_Joint: errors now, feedforward acceleration at the window's end; the forces are
    // solved on the state predicted for the window's end (desired path plus today's errors), so
    // that the forces reached at t + T suit the state there.
    qdd_des = ad_f;
    for (int c : tracked)
      qdd_des[c] = ka[c] * ad_f[c] + kv[c] * (ud_i[c] - x[nq + c]) + kp[c] * (qd_i[c] - x[c]);
    x_pred = x;
    x_pred.head(nq) = qd_f - (qd_i - x.head(nq));
    x_pred.segment(nq, nq) = ud_f - (ud_i - x.segment(nq, nq));
    control_ranges_at(t);
    if (!sys.compliant_tendons) {
      // Rigid tendons: the activations reachable by the window's end bound the forces.
      for (int m = 0; m < nm; ++m) {
        const double a = x[sys.activation_index(m)];
        a_lo[m] = thelen_activation_after(model.muscles[m], a, u_min[m], T);
        a_hi[m] = thelen_activation_after(model.muscles[m], a, u_max[m], T);
      }
    } else {
      // Compliant tendons: each muscle's force is predicted from its state now.
      Eigen::VectorXd controls_now = control_prev;
      muscle_driven_derivatives(sys, t, x, excitation, controls_now, ws, xdot);
      path_start = ws.geometry.length_m;
      for (int m = 0; m < nm; ++m) predictor_start[m] = {ws.fiber_velocity_m_s[m]};  // the predictions' common start
      use_fiber_state = true;
    }
    const bool feasible = solve_forces(tf, x_pred);
    ++r.summary.windows;
    if (!feasible) ++r.summary.windows_infeasible;
    for (int m = 0; m < nm; ++m) {
      if (use_fiber_state) {
        // The excitation whose force at the window's end is the solution's (it rises with excitation).
        const Muscle& mu = model.muscles[m];
        const double a0 = x[sys.activation_index(m)], lm0 = x[sys.fiber_length_index(m)];
        const double target = sol[m] * f_opt[m];
        double u_lo = u_min[m], u_hi = u_max[m];
        auto force = [&](double u) {
          return muscles::compliant_muscle_after(mu, a0, lm0, path_start[m], path_end[m], u, T, &predictor_start[m]).force_N;
        };
        if (target <= lo[m] * f_opt[m] + 1e-9) {
          excitation[m] = u_lo;
        } else if (target >= hi[m] * f_opt[m] - 1e-9) {
          excitation[m] = u_hi;
        } else {
          // Illinois (regula falsi with the stale end's value halved): the force is smooth and
          // monotonic in the excitation, so this converges in a handful of predictions. The first
          // try is the muscle's last excitation where it lies inside the bracket (excitations change
          // little between windows): 3.1 predictions per search on gait10dof18musc instead of 4.2.
          double f_lo = lo[m] * f_opt[m] - target, f_hi = hi[m] * f_opt[m] - target, u = u_lo;
          int side = 0;
          for (int i = 0; i < 30; ++i) {
            u = i == 0 && excitation[m] > u_lo && excitation[m] < u_hi ? excitation[m]
                                                                       : (u_lo * f_hi - u_hi * f_lo) / (f_hi - f_lo);
            const double fu = force(u) - target;
            if (std::abs(fu) < 1e-4 * mu.max_isometric_force_N || u_hi - u_lo < 1e-7) break;
            if ((fu < 0) == (f_lo < 0)) {
              u_lo = u;
              f_lo = fu;
              if (side == -1) f_hi *= 0.5;
              side = -1;
            } else {
              u_hi = u;
              f_hi = fu;
              if (side == 1) f_lo *= 0.5;
              side = 1;
            }
          }
          excitation[m] = u;
        }
        continue;
      }
      const double a_target = activation_for_solution(m, a_lo[m], a_hi[m]);
      excitation[m] = thelen_excitation_for(model.muscles[m], x[sys.activation_index(m)], a_target, T, u_min[m], u_max[m]);
    }
    control_new = sol.tail(na);
    // The evaluation at (t, x) above serves the window's start once its activation rates follow the new
    // excitations (its controls are the window's ramps' start; not so for step controls, nor where the
    // actuators are re-solved per interval).
    start_fresh = sys.compliant_tendons && !step_controls && !options.refresh_actuators;
    if (start_fresh)
      for (int m = 0; m < nm; ++m)
        xdot[sys.activation_index(m)] = thelen_activation_rate(model.muscles[m], excitation[m], x[sys.activation_index(m)]);
    if (t >= t_out - 1e-9) {
      Eigen::VectorXd c(nx);
      if (r.control_time_s.empty()) {  // the node in force at the first output time
        c << excitation, control_prev;
        r.control_time_s.push_back(t);
        rec_controls.push_back(c);
      }
      c << excitation, control_new;
      r.control_time_s.push_back(tf);
      rec_controls.push_back(c);
      r.window_time_s.push_back(t);
      rec_perr.push_back(qd_i - x.head(nq));
    }

    // Integrate the window, recording every dt_out.
    const double t_window = t;
    auto controls_at = [&](double time) {
      const double s = std::clamp((time - t_window) / T, 0.0, 1.0);
      for (int j = 0; j < na; ++j) control_now[j] = steps[nm + j] ? control_new[j] : control_prev[j] + s * (control_new[j] - control_prev[j]);
    };
    int evaluations_since_prepare = 0;  // by f since the last step began; more than one: a step was retried
    auto f = [&](double time, const Eigen::VectorXd& y, Eigen::VectorXd& dy) {
      ++evaluations_since_prepare;
      controls_at(time);
      stage_derivatives(time, y, dy);
    };
    // Without contact spheres the Jacobian is formed at the window's start and again after a step
    // that had to be retried (ROS2 is a W-method: any W keeps its order, but a stale one loses the
    // stiff parts' stability). Against forming it every 1 ms output interval: gait10dof18musc takes
    // as many steps (2786 against 2784) on 6.5 % fewer instructions, subject01 1 % more instructions,
    // the leg6dof9musc swing 897 steps instead of 909 (callgrind). Once per window without the retry
    // rule failed that swing (28 of 50 windows infeasible, 1642 steps). On contact spheres it is
    // formed every step: a sphere touching down changes it within the interval, and reusing it there
    // took 6 % more steps and doubled mtp_r's error.
    bool form_jacobian = true;
    auto prepare = [&](double time, const Eigen::VectorXd& y, Eigen::VectorXd& f0) {
      controls_at(time);
      const bool retried = evaluations_since_prepare > (options.integrator == CmcIntegrator::kRos34pw2 ? 3 : 1);
      evaluations_since_prepare = 0;
      if (start_fresh && &y == &x) {
        start_fresh = false;
        f0 = xdot;
        muscle_driven_jacobian(sys, y, excitation, ws, jac, f0);
        form_jacobian = false;
        muscle_forces_at_x(ws.muscle_force_N);
        return;
      }
      if (form_jacobian || retried || sys.contacts) {
        muscle_driven_prepare(sys, time, y, excitation, control_now, ws, jac, f0);
      } else {
        stage_derivatives(time, y, f0);
      }
      form_jacobian = false;
      muscle_forces_at_x(ws.muscle_force_N);
    };
    auto w_solve = [&](double gamma_h, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) {
      muscle_driven_w_solve(sys, jac, gamma_h, rhs, k);
    };
    // The window is integrated in one piece and the states between steps are interpolated (positions
    // cubic with their speeds, the rest linear; ROS34PW2's steps on subject01 average 1.2 ms).
    // Ending a step at every output time cost 15-20 % more steps (measured with ROS2). The
    // Dormand-Prince option and the per-interval actuator re-solve still stop at each output time.
    const bool output_phase = reset_done && t_window >= t_out - 1e-9;
    const int n_out = std::max(1, static_cast<int>(std::lround(T / dt_out)));
    const bool rosenbrock = options.integrator != CmcIntegrator::kDormandPrince;
    const bool dense = rosenbrock && !options.refresh_actuators;
    const int n_sub = dense ? 1 : n_out;
    int next_out = 1;  // the next output time inside the window: t_window + T next_out / n_out
    Eigen::VectorXd x_out(x.size());
    auto record_between = [&](double ta_s, const Eigen::VectorXd& xa, double tb_s, const Eigen::VectorXd& xb) {
      for (; next_out < n_out; ++next_out) {
        const double to = t_window + T * next_out / n_out;
        if (to > tb_s + 1e-12) break;
        const double h = tb_s - ta_s, th = h > 0 ? (to - ta_s) / h : 1.0;
        x_out = xa + th * (xb - xa);
        // Positions: the cubic through both ends with their rates (the speeds, also states).
        const double th2 = th * th, th3 = th2 * th;
        x_out.head(nq) = (2 * th3 - 3 * th2 + 1) * xa.head(nq) + (th3 - 2 * th2 + th) * h * xa.segment(nq, nq) +
                         (3 * th2 - 2 * th3) * xb.head(nq) + (th3 - th2) * h * xb.segment(nq, nq);
        if (coupled) assemble_coordinate_constraints(model, x_out.data(), x_out.data() + nq);
        r.time_s.push_back(to);
        rec_x.push_back(x_out);
        controls_at(to);
        Eigen::VectorXd actuator_force(na);
        for (int j = 0; j < na; ++j) actuator_force[j] = control_now[j] * sys.actuators->spec(j).optimal_force;
        rec_fa.push_back(actuator_force);
        rec_fm.push_back(force_at_step_start);  // completed by muscle_forces_at_x
        pending.emplace_back(rec_fm.size() - 1, th);
      }
    };
    const WStepDone step_done = dense && output_phase ? WStepDone(record_between) : WStepDone();
    for (int k = 0; k < n_sub; ++k) {
      const double ta = t_window + T * k / n_sub, tb = t_window + T * (k + 1) / n_sub;
      if (output_phase && k == 0) {
        for (int j = 0; j < na; ++j) control_now[j] = steps[nm + j] ? control_new[j] : control_prev[j];
        record(ta, x);
      }
      if (options.refresh_actuators) {
        // Inner loop (see the header): the ideal actuators re-solved for this sub-interval at the
        // current state, the muscles' forces as they are.
        Eigen::VectorXd qa(nq), ua(nq), aa(nq), qb(nq), ub(nq), ab(nq);
        trajectories_at(traj, ta, qa, ua, aa);
        trajectories_at(traj, tb, qb, ub, ab);
        Eigen::VectorXd acc = ab;
        for (int c : tracked) acc[c] = ka[c] * ab[c] + kv[c] * (ua[c] - x[nq + c]) + kp[c] * (qa[c] - x[c]);
        Eigen::VectorXd zero_controls = Eigen::VectorXd::Zero(na);
        muscle_driven_derivatives(sys, ta, x, excitation, zero_controls, ws, xdot);
        Eigen::VectorXd lam, c_act;
        if (coupled) {
          // The free rows only, with the coupled coordinates' accelerations following the others'.
          apply_coupler_rates(model, ws.x_coupled.data(), Eigen::VectorXd(ws.x_coupled.segment(nq, nq)).data(), acc.data());
          const Eigen::VectorXd rhs = ws.G.transpose() * (fd.M * acc + fd.bias - ws.tau);
          minimize_power_sum(ws.G.transpose() * ws.actuator_columns, rhs, u_min.tail(na), u_max.tail(na), qp, lam, c_act);
        } else {
          const Eigen::VectorXd rhs = fd.M * acc + fd.bias - ws.tau;
          minimize_power_sum(ws.actuator_columns, rhs, u_min.tail(na), u_max.tail(na), qp, lam, c_act);
        }
        control_prev = c_act;
        control_new = c_act;
        for (int j = 0; j < na; ++j) control_now[j] = c_act[j];
      }
      form_jacobian = true;
      const DormandPrinceSummary ds = options.integrator == CmcIntegrator::kRosenbrockW ? integrate_ros2(f, prepare, w_solve, ta, tb, x, ro, step_done)
                                      : options.integrator == CmcIntegrator::kRos34pw2 ? integrate_ros34pw2(f, prepare, w_solve, ta, tb, x, ro, step_done)
                                                                                      : integrate_dormand_prince(f, ta, tb, x, io);
      io.initial_step_s = ro.initial_step_s = ds.last_step_s;
      r.summary.integrator_steps += ds.accepted_steps;
      r.summary.integrator_rejected += ds.rejected_steps;
      r.summary.evaluations += ds.evaluations;
      if (!ds.success) throw std::runtime_error("CMC: the forward integration failed at " + std::to_string(ta) + " s: " + ds.message);
      if (coupled) assemble_coordinate_constraints(model, x.data(), x.data() + nq);  // against drift, as OpenSim projects
      if (k + 1 < n_sub && output_phase) {
        const double s = double(k + 1) / n_sub;
        for (int j = 0; j < na; ++j) control_now[j] = steps[nm + j] ? control_new[j] : control_prev[j] + s * (control_new[j] - control_prev[j]);
        record(tb, x);
      }
    }
    control_prev = control_new;
    t = tf;
    if (progress) progress->report(double(w + 1) / n_windows, "computed muscle control");
  }
  for (int j = 0; j < na; ++j) control_now[j] = control_prev[j];
  record(t, x);

  // Tables.
  const int ns = static_cast<int>(r.time_s.size()), nw = static_cast<int>(r.window_time_s.size());
  r.q.resize(ns, nq);
  r.u.resize(ns, nq);
  r.activation.resize(ns, nm);
  r.fiber_length_m.resize(ns, nm);
  r.muscle_force_N.resize(ns, nm);
  r.actuator_force.resize(ns, na);
  for (int i = 0; i < ns; ++i) {
    r.q.row(i) = rec_x[i].head(nq).transpose();
    r.u.row(i) = rec_x[i].segment(nq, nq).transpose();
    r.activation.row(i) = rec_x[i].segment(2 * nq, nm).transpose();
    r.muscle_force_N.row(i) = rec_fm[i].transpose();
    r.actuator_force.row(i) = rec_fa[i].transpose();
  }
  // Fibre lengths (rigid tendon) from the recorded poses.
  {
    KinematicsWorkspace<double> kws(model);
    MotionSubspace S(model);
    MusclePathGeometry g(model);
    for (int i = 0; i < ns; ++i) {
      const Eigen::VectorXd q = r.q.row(i).transpose(), u = r.u.row(i).transpose();
      forward_kinematics(model, q.data(), kws);
      motion_subspace(model, q.data(), kws, S);
      muscle_path_geometry(model, q.data(), u.data(), kws, S, g);
      for (int m = 0; m < nm; ++m)
        r.fiber_length_m(i, m) = sys.compliant_tendons ? rec_x[i][sys.fiber_length_index(m)]
                                                      : muscles::rigid_tendon_fiber_length(model.muscles[m], g.length_m[m]);
    }
  }
  r.controls.resize(rec_controls.size(), nx);
  for (std::size_t i = 0; i < rec_controls.size(); ++i) r.controls.row(i) = rec_controls[i].transpose();
  r.position_error.resize(nw, nq);
  for (int i = 0; i < nw; ++i) r.position_error.row(i) = rec_perr[i].transpose();
  r.summary.simulated_s = t - t_out;
  r.summary.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  if (r.summary.windows_residuals_unbounded)
    r.summary.warnings.push_back(std::to_string(r.summary.windows_residuals_unbounded) + " of " + std::to_string(r.summary.windows) +
                                 " windows needed the residual actuators beyond their control constraints");
  if (r.summary.windows_infeasible)
    r.summary.warnings.push_back(std::to_string(r.summary.windows_infeasible) + " of " + std::to_string(r.summary.windows) +
                                 " windows could not meet the task accelerations within the control constraints "
                                 "(the closest forces were applied; add reserve actuators or widen their ranges)");
  return r;
}

std::vector<std::pair<std::string, double>> ComputedMuscleControlResult::average_residuals() const {
  std::vector<std::pair<std::string, double>> out;
  for (int j : residual_actuators) out.emplace_back(actuator_names[j], actuator_force.rows() ? actuator_force.col(j).mean() : 0.0);
  return out;
}

Eigen::VectorXd ComputedMuscleControlResult::position_error_rms() const {
  if (position_error.rows() == 0) return Eigen::VectorXd::Zero(position_error.cols());
  return (position_error.array().square().colwise().mean()).sqrt().transpose();
}

std::string ComputedMuscleControlSummary::BriefReport() const {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "CMC: %d windows (%d infeasible, %d with residuals beyond their constraints), %.3f s simulated in %.2f s "
                "(%.1fx real time), %ld integrator steps (%ld rejected, %ld evaluations), external forces: %s",
                windows, windows_infeasible, windows_residuals_unbounded, simulated_s, solve_seconds, real_time_factor(), integrator_steps,
                integrator_rejected, evaluations, external_forces.c_str());
  return buf;
}

Storage cmc_controls_table(const ComputedMuscleControlResult& r) {
  std::vector<std::string> names;
  for (const auto& m : r.muscle_names) names.push_back(m + ".excitation");
  for (const auto& a : r.actuator_names) names.push_back(a + ".excitation");
  return make_storage("Controls", names, r.control_time_s, r.controls, false);
}

Storage cmc_states_table(const ComputedMuscleControlResult& r) {
  std::vector<std::string> names;
  const int nq = static_cast<int>(r.coordinate_names.size()), nm = static_cast<int>(r.muscle_names.size());
  for (const auto& c : r.coordinate_names) names.push_back(c);
  for (const auto& c : r.coordinate_names) names.push_back(c + "_u");
  for (const auto& m : r.muscle_names) names.push_back(m + ".activation");
  for (const auto& m : r.muscle_names) names.push_back(m + ".fiber_length");
  Eigen::MatrixXd v(r.time_s.size(), 2 * nq + 2 * nm);
  v << r.q, r.u, r.activation, r.fiber_length_m;
  return make_storage("States", names, r.time_s, v, false);
}

Storage cmc_kinematics_q_table(const Model& model, const ComputedMuscleControlResult& r) {
  return make_storage("Coordinates", r.coordinate_names, r.time_s, coordinates_in_file_units(model, r.q), true);
}

Storage cmc_position_error_table(const ComputedMuscleControlResult& r) {
  return make_storage("PositionErrors", r.coordinate_names, r.window_time_s, r.position_error, false);
}

Storage cmc_actuation_force_table(const ComputedMuscleControlResult& r) {
  std::vector<std::string> names = r.muscle_names;
  names.insert(names.end(), r.actuator_names.begin(), r.actuator_names.end());
  Eigen::MatrixXd v(r.time_s.size(), names.size());
  v << r.muscle_force_N, r.actuator_force;
  return make_storage("ActuatorForces", names, r.time_s, v, false);
}

std::string cmc_average_residuals_text(const ComputedMuscleControlResult& r) {
  std::string s = "Average Residuals:\n\n";
  char buf[160];
  for (const auto& [name, value] : r.average_residuals()) {
    std::snprintf(buf, sizeof buf, "%s average = %g\n", name.c_str(), value);
    s.append(buf);
  }
  return s;
}

}  // namespace cpgait
