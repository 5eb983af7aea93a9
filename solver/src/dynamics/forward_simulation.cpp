#include "cpgait/dynamics/forward_simulation.h"

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/dynamics/coordinate_couplers.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/muscles/muscle_model.h"

namespace cpgait {

namespace {
std::vector<std::string> control_names(const Model& model, const ResolvedActuators& actuators) {
  std::vector<std::string> names;
  for (const auto& m : model.muscles) names.push_back(m.name);
  for (int j = 0; j < actuators.size(); ++j) names.push_back(actuators.spec(j).name);
  return names;
}
}  // namespace

void ControlHistory::at(double t, Eigen::VectorXd& out) const {
  const int n = static_cast<int>(time_s.size());
  out.resize(values.cols());
  if (n == 1 || t <= time_s.front()) {
    out = values.row(0).transpose();
    return;
  }
  if (t >= time_s.back()) {
    out = values.row(n - 1).transpose();
    return;
  }
  const int i = static_cast<int>(std::upper_bound(time_s.begin(), time_s.end(), t) - time_s.begin()) - 1;
  const double w = (t - time_s[i]) / (time_s[i + 1] - time_s[i]);
  for (int c = 0; c < values.cols(); ++c)
    out[c] = use_steps[c] ? (w > 1e-12 ? values(i + 1, c) : values(i, c)) : (1 - w) * values(i, c) + w * values(i + 1, c);
}

ControlHistory control_history_from_table(const Model& model, const ResolvedActuators& actuators, const Storage& table,
                                          std::vector<std::string>* missing) {
  const auto names = control_names(model, actuators);
  const int nm = static_cast<int>(model.muscles.size());
  ControlHistory h;
  const Eigen::VectorXd t = table.time();
  h.time_s.assign(t.data(), t.data() + t.size());
  if (h.time_s.empty()) throw InputError(table.name, 0, "nRows", "the controls file has no rows");
  h.values.resize(table.num_rows(), names.size());
  h.use_steps.assign(names.size(), false);
  for (std::size_t c = 0; c < names.size(); ++c) {
    int col = table.column(names[c] + ".excitation");
    if (col < 0) col = table.column(names[c]);
    h.use_steps[c] = static_cast<int>(c) < nm;  // muscles held over each interval, as CMC computed them
    if (col < 0) {
      if (missing) missing->push_back(names[c]);
      h.values.col(c).setConstant(static_cast<int>(c) < nm ? model.muscles[c].min_control : 0.0);
      continue;
    }
    h.values.col(c) = table.data.col(col);
  }
  return h;
}

ControlHistory control_history_from_control_set(const Model& model, const ResolvedActuators& actuators,
                                                const ControlSetSpec& set, const std::string& file,
                                                std::vector<std::string>* missing) {
  const auto names = control_names(model, actuators);
  const int nm = static_cast<int>(model.muscles.size());
  // All node times, merged.
  std::vector<double> times;
  for (const auto& c : set.controls) times.insert(times.end(), c.node_times_s.begin(), c.node_times_s.end());
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end(), [](double a, double b) { return std::abs(a - b) < 1e-12; }), times.end());
  if (times.empty()) throw InputError(file, 0, "x_nodes", "the control set holds no control nodes");
  ControlHistory h;
  h.time_s = times;
  h.values.resize(times.size(), names.size());
  h.use_steps.assign(names.size(), false);
  for (std::size_t c = 0; c < names.size(); ++c) {
    const ControlBounds* b = nullptr;
    for (const auto& k : set.controls)
      if (k.name == names[c]) b = &k;
    if (!b || b->node_times_s.empty()) {
      if (missing) missing->push_back(names[c]);
      h.values.col(c).setConstant(static_cast<int>(c) < nm ? model.muscles[c].min_control : 0.0);
      h.use_steps[c] = static_cast<int>(c) < nm;
      continue;
    }
    h.use_steps[c] = b->use_steps;
    ControlHistory one;
    one.time_s = b->node_times_s;
    one.values = Eigen::Map<const Eigen::VectorXd>(b->node_values.data(), b->node_values.size());
    one.use_steps = {b->use_steps};
    Eigen::VectorXd v;
    for (std::size_t i = 0; i < times.size(); ++i) {
      one.at(times[i], v);
      h.values(i, c) = v[0];
    }
  }
  return h;
}

Eigen::VectorXd initial_state_from_table(const Model& model, const Storage& states, double t, bool compliant,
                                         std::vector<std::string>* warnings) {
  const int nq = model.num_coordinates(), nm = static_cast<int>(model.muscles.size());
  const Eigen::VectorXd time = states.time();
  int row = 0;
  for (int i = 0; i < states.num_rows(); ++i)
    if (time[i] <= t + 1e-9) row = i;
  const bool degrees = states.in_degrees.value_or(false);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(2 * nq + (compliant ? 2 : 1) * nm);
  for (int c = 0; c < nq; ++c) {
    const auto& co = model.coordinates[c];
    const int cq = states.column(co.name), cu = states.column(co.name + "_u");
    const double k = degrees && co.is_angle() ? M_PI / 180 : 1.0;
    if (cq < 0) {
      if (warnings) warnings->push_back("the states file has no '" + co.name + "': its default value is used");
      x[c] = co.default_value;
    } else {
      x[c] = states.data(row, cq) * k;
    }
    if (cu >= 0) x[nq + c] = states.data(row, cu) * k;
    else if (warnings) warnings->push_back("the states file has no '" + co.name + "_u': it starts at rest");
  }
  KinematicsWorkspace<double> kws(model);
  MotionSubspace S(model);
  MusclePathGeometry g(model);
  forward_kinematics(model, x.data(), kws);
  motion_subspace(model, x.data(), kws, S);
  muscle_path_geometry(model, x.data(), x.data() + nq, kws, S, g);
  for (int m = 0; m < nm; ++m) {
    const auto& mu = model.muscles[m];
    const int ca = states.column(mu.name + ".activation"), cl = states.column(mu.name + ".fiber_length");
    x[2 * nq + m] = ca >= 0 ? states.data(row, ca) : std::max(mu.min_control, 0.02);
    if (!compliant) continue;
    x[2 * nq + nm + m] = cl >= 0 ? states.data(row, cl)
                                 : muscles::compliant_equilibrium_fiber_length(mu, x[2 * nq + m], g.length_m[m],
                                                                                  g.lengthening_speed_m_s[m]);
  }
  return x;
}

ForwardSimulationResult forward_simulation(const Model& model, const ResolvedActuators& actuators, const AppliedLoads* loads,
                                           const ContactSet* contacts, const ControlHistory& controls,
                                           const Eigen::VectorXd& x0, const ForwardSimulationOptions& o,
                                           const Storage* desired, Progress* progress) {
  const auto start = std::chrono::steady_clock::now();
  ForwardSimulationResult r;
  MuscleDrivenSystem sys;
  sys.model = &model;
  sys.actuators = actuators.size() ? &actuators : nullptr;
  sys.loads = loads;
  sys.contacts = loads ? nullptr : contacts;
  sys.compliant_tendons = o.compliant_tendons;
  r.external_forces = loads ? "measured loads" : (sys.contacts ? "contact spheres" : "none");
  const int nq = sys.num_coordinates(), nm = sys.num_muscles(), na = sys.num_actuators();
  if (x0.size() != sys.state_size())
    throw std::invalid_argument("forward_simulation: the initial state has " + std::to_string(x0.size()) + " values, the model " +
                                std::to_string(sys.state_size()));
  r.coordinate_names = coordinate_names(model);
  for (const auto& m : model.muscles) r.muscle_names.push_back(m.name);
  for (int j = 0; j < na; ++j) r.actuator_names.push_back(actuators.spec(j).name);
  if (sys.contacts)
    for (const auto& s : sys.contacts->spheres) r.contact_names.push_back(s.name);

  const bool correcting = o.correction_kp || o.correction_kv;
  std::optional<CoordinateTrajectories> want;
  if (correcting) {
    if (!desired) throw std::invalid_argument("forward_simulation: the correction controller needs desired coordinates");
    want = coordinate_trajectories(model, *desired, {});
    r.warnings.insert(r.warnings.end(), want->warnings.begin(), want->warnings.end());
  }


  MuscleDrivenWorkspace ws(sys);
  MuscleDrivenJacobian jac;
  Eigen::VectorXd all, excitation(nm), control(na), x = x0, xdot(x.size()), qd(nq), ud(nq), ad(nq);
  auto inputs_at = [&](double t) {
    controls.at(t, all);
    excitation = all.head(nm);
    control = all.tail(na);
  };
  // The correction controller acts as generalized forces on every coordinate (OpenSim adds one
  // coordinate actuator per coordinate); they enter the accelerations through M^-1.
  auto f = [&](double t, const Eigen::VectorXd& y, Eigen::VectorXd& dy) {
    inputs_at(t);
    muscle_driven_derivatives(sys, t, y, excitation, control, ws, dy);
    if (correcting) {
      trajectories_at(*want, t, qd, ud, ad);
      const Eigen::VectorXd tau = o.correction_kp.value_or(0) * (qd - y.head(nq)) + o.correction_kv.value_or(0) * (ud - y.segment(nq, nq));
      dy.segment(nq, nq) += ws.fd.llt.solve(tau);
    }
  };
  auto prepare = [&](double t, const Eigen::VectorXd& y, Eigen::VectorXd& f0) {
    inputs_at(t);
    muscle_driven_prepare(sys, t, y, excitation, control, ws, jac, f0);
    if (correcting) {
      trajectories_at(*want, t, qd, ud, ad);
      const Eigen::VectorXd tau = o.correction_kp.value_or(0) * (qd - y.head(nq)) + o.correction_kv.value_or(0) * (ud - y.segment(nq, nq));
      f0.segment(nq, nq) += ws.fd.llt.solve(tau);
    }
  };
  auto w_solve = [&](double gh, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) { muscle_driven_w_solve(sys, jac, gh, rhs, k); };

  RosenbrockOptions ro;
  ro.relative_tolerance = ro.absolute_tolerance = o.integrator_tolerance;
  ro.max_step_s = 0.01;
  std::vector<Eigen::VectorXd> rec_x, rec_fm, rec_fa, rec_c;
  auto record = [&](double t) {
    if (ws.constrained) assemble_coordinate_constraints(model, x.data(), x.data() + nq);  // against drift, as OpenSim projects
    f(t, x, xdot);
    r.time_s.push_back(t);
    rec_x.push_back(x);
    rec_fm.push_back(ws.muscle_force_N);
    rec_fa.push_back(ws.actuator_force);
    Eigen::VectorXd c(3 * r.contact_names.size());
    for (std::size_t s = 0; s < r.contact_names.size(); ++s) c.segment<3>(3 * s) = ws.contact_force_N[s];
    rec_c.push_back(c);
  };
  const int n_out = std::max(1, static_cast<int>(std::lround((o.t1_s - o.t0_s) / o.output_interval_s)));
  record(o.t0_s);
  for (int k = 0; k < n_out; ++k) {
    if (progress && progress->cancelled()) throw std::runtime_error("forward simulation cancelled");
    const double ta = o.t0_s + (o.t1_s - o.t0_s) * k / n_out, tb = o.t0_s + (o.t1_s - o.t0_s) * (k + 1) / n_out;
    const auto s = integrate_ros2(f, prepare, w_solve, ta, tb, x, ro);
    ro.initial_step_s = s.last_step_s;
    r.integrator_steps += s.accepted_steps;
    r.evaluations += s.evaluations;
    if (!s.success || !x.allFinite()) {
      r.warnings.push_back("the simulation stopped at " + std::to_string(ta) + " s: " + (s.success ? "the state is not finite" : s.message));
      break;
    }
    record(tb);
    if (progress) progress->report(double(k + 1) / n_out, "forward simulation");
  }
  const int ns = static_cast<int>(r.time_s.size());
  r.q.resize(ns, nq);
  r.u.resize(ns, nq);
  r.activation.resize(ns, nm);
  r.fiber_length_m.resize(ns, sys.compliant_tendons ? nm : 0);
  r.muscle_force_N.resize(ns, nm);
  r.actuator_force.resize(ns, na);
  r.contact_force_N.resize(ns, 3 * r.contact_names.size());
  for (int i = 0; i < ns; ++i) {
    r.q.row(i) = rec_x[i].head(nq).transpose();
    r.u.row(i) = rec_x[i].segment(nq, nq).transpose();
    r.activation.row(i) = rec_x[i].segment(2 * nq, nm).transpose();
    if (sys.compliant_tendons) r.fiber_length_m.row(i) = rec_x[i].segment(2 * nq + nm, nm).transpose();
    r.muscle_force_N.row(i) = rec_fm[i].transpose();
    r.actuator_force.row(i) = rec_fa[i].transpose();
    r.contact_force_N.row(i) = rec_c[i].transpose();
  }
  r.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

std::string ForwardSimulationResult::BriefReport() const {
  char buf[300];
  const double simulated = time_s.empty() ? 0 : time_s.back() - time_s.front();
  std::snprintf(buf, sizeof buf, "Forward: %.3f s simulated in %.2f s (%.1fx real time), %ld integrator steps, %ld evaluations, external forces: %s",
                simulated, solve_seconds, solve_seconds > 0 ? simulated / solve_seconds : 0.0, integrator_steps, evaluations,
                external_forces.c_str());
  return buf;
}

Storage forward_states_table(const ForwardSimulationResult& r) {
  std::vector<std::string> names;
  for (const auto& c : r.coordinate_names) names.push_back(c);
  for (const auto& c : r.coordinate_names) names.push_back(c + "_u");
  for (const auto& m : r.muscle_names) names.push_back(m + ".activation");
  if (r.fiber_length_m.cols())
    for (const auto& m : r.muscle_names) names.push_back(m + ".fiber_length");
  Eigen::MatrixXd v(r.time_s.size(), names.size());
  v << r.q, r.u, r.activation, r.fiber_length_m;
  return make_storage("States", names, r.time_s, v, false);
}

Storage forward_kinematics_q_table(const Model& model, const ForwardSimulationResult& r) {
  return make_storage("Coordinates", r.coordinate_names, r.time_s, coordinates_in_file_units(model, r.q), true);
}

Storage forward_actuation_force_table(const ForwardSimulationResult& r) {
  std::vector<std::string> names = r.muscle_names;
  names.insert(names.end(), r.actuator_names.begin(), r.actuator_names.end());
  Eigen::MatrixXd v(r.time_s.size(), names.size());
  v << r.muscle_force_N, r.actuator_force;
  return make_storage("ActuatorForces", names, r.time_s, v, false);
}

Storage forward_contact_force_table(const ForwardSimulationResult& r) {
  std::vector<std::string> names;
  for (const auto& s : r.contact_names)
    for (const char* a : {"_force_x", "_force_y", "_force_z"}) names.push_back(s + a);
  return make_storage("ContactForces", names, r.time_s, r.contact_force_N, false);
}

}  // namespace cpgait
