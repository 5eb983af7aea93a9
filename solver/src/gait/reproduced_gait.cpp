#include "cpgait/gait/reproduced_gait.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>

#include "cpgait/capture/input_error.h"
#include "cpgait/cpg/cpg_phase.h"
#include "cpgait/cpg/matsuoka.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/gait/standing_pose.h"
#include "cpgait/gait/walk_measures.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/muscle_model.h"

namespace cpgait {

namespace {

// The trial's cycle averaged at kPhases phases from the heel strike: the reflex's targets at the
// CPG's phase (issue 22), so that the speed knob and the stop change them too.
struct PhaseTemplate {
  static constexpr int kPhases = 100;
  std::vector<Eigen::VectorXd> q, u, a;  // per phase sample; rates in the trial's time

  // The template at a phase (linear between samples, round the cycle), rates in simulated time at
  // speed knob `speed`; the coordinates marked in `keep` (the root's translations) keep the
  // time-indexed reference's values already in q_ref, u_ref, a_ref.
  void at(double phase, double speed, const std::vector<char>& keep, Eigen::VectorXd& q_ref, Eigen::VectorXd& u_ref,
          Eigen::VectorXd& a_ref) const {
    const double pos = phase * kPhases;
    const int i = static_cast<int>(std::floor(pos)) % kPhases, j = (i + 1) % kPhases;
    const double w = pos - std::floor(pos);
    for (Eigen::Index c = 0; c < q_ref.size(); ++c) {
      if (keep[static_cast<std::size_t>(c)]) continue;
      // An angle that wraps between samples would interpolate through the long way; gait's do not.
      q_ref[c] = (1 - w) * q[i][c] + w * q[j][c];
      u_ref[c] = speed * ((1 - w) * u[i][c] + w * u[j][c]);
      a_ref[c] = speed * speed * ((1 - w) * a[i][c] + w * a[j][c]);
    }
  }
};

// The mean of `cycles` cycles of ref from start_s, each cycle_s long.
PhaseTemplate phase_template(const CoordinateTrajectories& ref, double start_s, double cycle_s, int cycles) {
  const Eigen::Index nq = ref.q.cols();
  PhaseTemplate t;
  Eigen::VectorXd q(nq), u(nq), a(nq);
  for (int j = 0; j < PhaseTemplate::kPhases; ++j) {
    t.q.push_back(Eigen::VectorXd::Zero(nq));
    t.u.push_back(Eigen::VectorXd::Zero(nq));
    t.a.push_back(Eigen::VectorXd::Zero(nq));
    for (int k = 0; k < cycles; ++k) {
      trajectories_at(ref, start_s + (k + static_cast<double>(j) / PhaseTemplate::kPhases) * cycle_s, q, u, a);
      t.q.back() += q / cycles, t.u.back() += u / cycles, t.a.back() += a / cycles;
    }
  }
  return t;
}

struct PassiveJoint {
  int c;
  double stiffness, damping, rest;
};

// The passive joints, the root's aside: those the options name (their spring-damper towards the
// default value), and those no muscle crosses (moment_arm_m at the start), which nothing else would
// hold: as a locked joint would, a critically damped 5 Hz spring-damper (from the mass matrix'
// diagonal M) towards the trial's mean. Without it gait10dof18musc's unmuscled lumbar joint swung the
// torso 164 deg RMS off the trial; with the toes' 300 N m/rad and 0.5 N m s/rad 30 deg - measured.
std::vector<PassiveJoint> passive_joints(const Model& model, const ReproducedGaitOptions& o, const std::vector<int>& root,
                                         const Eigen::MatrixXd& moment_arm_m, const Eigen::MatrixXd& M, const CoordinateTrajectories& ref) {
  std::vector<PassiveJoint> passive;
  const int nm = static_cast<int>(model.muscles.size());
  for (int c = 0; c < model.num_coordinates(); ++c) {
    if (std::find(root.begin(), root.end(), c) != root.end() || model.coordinates[c].locked ||
        std::any_of(model.couplers.begin(), model.couplers.end(), [c](const CoordinateCoupler& k) { return k.dependent == c; }))
      continue;
    if (!o.passive_coordinate_prefix.empty() && model.coordinates[c].name.rfind(o.passive_coordinate_prefix, 0) == 0) {
      passive.push_back({c, o.passive_stiffness_Nm_per_rad, o.passive_damping_Nms_per_rad, model.coordinates[c].default_value});
    } else if (nm > 0 && moment_arm_m.col(c).cwiseAbs().maxCoeff() == 0.0) {
      const double w = 2 * M_PI * 5.0, inertia = M(c, c);
      passive.push_back({c, w * w * inertia, 2 * w * inertia, ref.q.col(c).mean()});
    }
  }
  return passive;
}

// The pelvis residuals at state x (positions, then speeds) into tau_root's root entries, given the
// accelerations xdot without them and M^-1's root columns. Translations: springs and dampers towards
// the reference, scaled by body mass, without feedforward, so weight and propulsion reach the body
// through the legs and the ground and the springs take only what the ground does not. Rotations:
// computed torque (the reference's accelerations plus PD), given the translational forces, so the
// trunk stays upright.
void pelvis_residuals(const Model& model, const std::vector<int>& root, const ReproducedGaitOptions& o, const Eigen::MatrixXd& Minv_root,
                      const Eigen::VectorXd& q_ref, const Eigen::VectorXd& u_ref, const Eigen::VectorXd& a_ref, const Eigen::VectorXd& x,
                      const Eigen::VectorXd& xdot, Eigen::VectorXd& tau_root) {
  const int nq = model.num_coordinates(), nr = static_cast<int>(root.size());
  const double body_mass_kg = model.total_mass_kg();
  std::vector<int> rotations;
  for (int i = 0; i < nr; ++i) {
    const int c = root[i];
    if (model.coordinates[c].is_angle()) rotations.push_back(i);
    else tau_root[c] = body_mass_kg * (o.pelvis_translation_kp * (q_ref[c] - x[c]) + o.pelvis_translation_kv * (u_ref[c] - x[nq + c]));
  }
  const int nrot = static_cast<int>(rotations.size());
  if (nrot == 0) return;
  const Eigen::VectorXd qdd_translations = Minv_root * Eigen::VectorXd(tau_root(root));  // rotations still 0
  Eigen::MatrixXd B(nrot, nrot);
  Eigen::VectorXd want(nrot);
  for (int a = 0; a < nrot; ++a) {
    const int c = root[rotations[a]];
    want[a] = a_ref[c] + o.pelvis_kv * (u_ref[c] - x[nq + c]) + o.pelvis_kp * (q_ref[c] - x[c]) - xdot[nq + c] - qdd_translations[c];
    for (int b2 = 0; b2 < nrot; ++b2) B(a, b2) = Minv_root(c, rotations[b2]);
  }
  const Eigen::VectorXd tr = B.partialPivLu().solve(want);
  for (int a = 0; a < nrot; ++a) tau_root[root[rotations[a]]] = tr[a];
}

}  // namespace

ReproducedGaitResult reproduce_gait(const Model& model, const CpgModel& cpg_in, const Storage& reference,
                                    const ContactSet& contacts_in, const ReproducedGaitOptions& o, Progress* progress,
                                    const ReproducedGaitCheckpoint* resume_from) {
  const auto clock_start = std::chrono::steady_clock::now();
  ReproducedGaitResult r;
  r.coordinate_names = coordinate_names(model);
  const int nq = model.num_coordinates(), nm = static_cast<int>(model.muscles.size());
  if (contacts_in.spheres.empty()) throw InputError(reference.name, 0, "contacts", "the reproduced gait needs contact spheres");
  if (!(o.control_interval_s > 0 && o.control_interval_s <= 0.01))
    throw InputError(reference.name, 0, "control_interval_s", "the controller's interval must lie in (0, 0.01] s, not " + std::to_string(o.control_interval_s));
  if (!(o.entrainment.share >= 0 && o.entrainment.share <= 1))
    throw InputError(reference.name, 0, "entrainment", "the share of the phase error made up at a touchdown must lie in [0, 1], not " +
                                                        std::to_string(o.entrainment.share));
  if (!(o.entrainment.time_s > 0))
    throw InputError(reference.name, 0, "entrainment.time_s", "the entrainment's time constant must be positive");
  // A treadmill's belt runs at the speed knob's pace too: the reference is time-scaled, its strides
  // keep their length, so the belt must move them back that much faster.
  ContactSet contacts = contacts_in;
  contacts.ground_velocity_m_s *= o.speed;
  const Eigen::Vector3d belt_velocity = contacts.ground_velocity_m_s;

  CpgModel cpg = cpg_in;
  cpg.speed = cpg_in.speed * o.speed;
  cpg.amplitude = cpg_in.amplitude * o.amplitude;
  const MatsuokaNetwork network = network_at_speed(cpg);
  std::vector<int> cpg_to_model(cpg.muscle_names.size(), -1);
  int matched = 0;
  for (std::size_t k = 0; k < cpg.muscle_names.size(); ++k) {
    cpg_to_model[k] = model.muscle_index(cpg.muscle_names[k]);
    matched += cpg_to_model[k] >= 0;
  }
  if (matched == 0) throw InputError("cpg", 0, "muscles", "none of the CPG's muscles is in model " + model.name);
  if (matched < nm) r.warnings.push_back(std::to_string(nm - matched) + " muscles have no CPG output and stay at their minimum excitation");

  // Feedback signals: coordinates (rad) or bodies (1 while their spheres press the ground).
  struct Signal {
    int coordinate = -1, body = -1;
  };
  std::vector<Signal> signals;
  for (const auto& name : cpg.feedback_signals) {
    Signal s;
    s.coordinate = model.coordinate_index(name);
    if (s.coordinate < 0) s.body = model.body_index(name);
    if (s.coordinate < 0 && s.body <= 0)
      throw InputError("cpg", 0, "feedback_signals", "'" + name + "' is neither a coordinate nor a body of model " + model.name);
    signals.push_back(s);
  }

  // The reference, its root coordinates, and the start.
  const CoordinateTrajectories ref = coordinate_trajectories(model, reference, {});
  r.warnings.insert(r.warnings.end(), ref.warnings.begin(), ref.warnings.end());
  // The reference at reference time tau, its rates scaled to simulated time by the speed knob.
  auto reference_at = [&](double tau, Eigen::VectorXd& q, Eigen::VectorXd& u, Eigen::VectorXd& a) {
    trajectories_at(ref, tau, q, u, a);
    u *= o.speed;
    a *= o.speed * o.speed;
  };

  const double ref_end = ref.time_s.back();
  const double tau_at_cpg_start = o.start_time_s + cpg.phase_at_start * cpg_in.cycle_s;  // the CPG's start state fits here
  const double tau0 = reproduced_gait_begin_s(cpg_in, ref.time_s.front(), ref_end, o);
  r.reference_begin_s = tau0;
  if (tau0 < ref.time_s.front() || tau0 > ref_end)
    throw InputError(reference.name, 0, o.begin_time_s >= 0 ? "begin_time" : "start_time",
                     "the simulation would begin outside the reference kinematics (begin time, or heel strike + the CPG's start phase)");
  const double tracked_until = std::min(o.duration_s, (ref_end - tau0) / o.speed);  // reference time available
  if (tracked_until < o.duration_s)
    r.warnings.push_back("the reference kinematics end after " + std::to_string(tracked_until) +
                         " s of simulated time: tracking errors and pelvis residuals use the reference up to there");
  std::vector<int> root;
  int pelvis_body = 0;  // the root's body
  for (const auto& j : model.joints)
    if (j.parent_body == 0) {
      root = j.coordinates;
      pelvis_body = j.child_body;
      break;
    }
  // The phase-indexed reference: the cycles after the heel strike averaged.
  PhaseTemplate phase_reference;
  CpgPhaseTable phase_table;
  int phase_nearest = -1;  // cpg_phase's hint: the last state's nearest sample
  if (o.phase_indexed_reference) {
    const int cycles = static_cast<int>(std::floor((ref_end - o.start_time_s) / cpg_in.cycle_s + 1e-9));
    if (o.start_time_s < ref.time_s.front() || cycles < 1)
      throw InputError(reference.name, 0, "start_time", "a phase-indexed reference needs a full gait cycle of the reference after the heel strike");
    phase_reference = phase_template(ref, o.start_time_s, cpg_in.cycle_s, cycles);
  }
  if (o.phase_indexed_reference || o.entrainment.share > 0) phase_table = cpg_phase_table(cpg_in);
  // Walk -> stand: the belt's share of its speed once the walk froze (frozen_at_s, < 0: walking),
  // easing to 0 over stop_over_s.
  const double stop_over_s = o.stop_over_s > 0 ? o.stop_over_s : 0.3;
  double frozen_at_s = -1, phase_before = -1;
  auto moving_share = [&](double t) {
    if (frozen_at_s < 0) return 1.0;
    const double s = std::min(1.0, (t - frozen_at_s) / stop_over_s);
    return 1.0 - s * s * (3 - 2 * s);
  };
  // The pelvis translations keep the time-indexed reference's (under the template and the stand).
  std::vector<char> root_translation(static_cast<std::size_t>(nq), 0);
  for (int c : root) root_translation[static_cast<std::size_t>(c)] = !model.coordinates[c].is_angle();
  for (int c : root) r.residual_names.push_back(model.coordinates[c].name + (model.coordinates[c].is_angle() ? "_moment" : "_force"));

  MuscleDrivenSystem sys;
  sys.model = &model;
  sys.contacts = &contacts;
  sys.compliant_tendons = o.compliant_tendons;
  for (const auto& s : contacts.spheres) r.contact_names.push_back(s.name);
  MuscleDrivenWorkspace ws(sys);
  MuscleDrivenJacobian jac;
  jac.whole_w = o.integrator == WMethod::kLinearlyImplicitEuler;  // no error control to bound its steps

  // Initial state on the reference, muscles at the CPG's excitations.
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), xdot(sys.state_size()), q_ref(nq), u_ref(nq), a_ref(nq);
  reference_at(tau0, q_ref, u_ref, a_ref);
  x.head(nq) = q_ref;
  x.segment(nq, nq) = u_ref;
  MatsuokaState neurons = cpg.start;
  MatsuokaScratch scratch;
  matsuoka_prepare(network, scratch);
  // Begun elsewhere than at the CPG's start phase: the network runs (without feedback) on its limit
  // cycle to the phase the reference has at the beginning.
  if (tau0 != tau_at_cpg_start) {
    double phase = (tau0 - tau_at_cpg_start) / cpg_in.cycle_s;
    phase -= std::floor(phase);
    const int n = static_cast<int>(std::lround(phase * cpg_in.cycle_s / cpg.speed / o.control_interval_s));
    const Eigen::VectorXd none = Eigen::VectorXd::Zero(network.size());
    for (int i = 0; i < n; ++i) matsuoka_step(network, neurons, o.control_interval_s, none, scratch);
  }
  const Eigen::SparseMatrix<double> output_map = cpg.output_map.sparseView();
  Eigen::VectorXd excitation(nm), no_controls(0);
  auto cpg_excitation_now = [&]() {
    for (int m = 0; m < nm; ++m) excitation[m] = model.muscles[m].min_control;
    const Eigen::VectorXd y = neurons.x.cwiseMax(0.0);
    const Eigen::VectorXd e = cpg_excitations(cpg, y, output_map);
    for (std::size_t k = 0; k < cpg_to_model.size(); ++k)
      if (cpg_to_model[k] >= 0) excitation[cpg_to_model[k]] = e[k];
  };
  cpg_excitation_now();
  for (int m = 0; m < nm; ++m) x[sys.activation_index(m)] = std::clamp(excitation[m], model.muscles[m].min_control, 1.0);
  muscle_driven_derivatives(sys, 0.0, x, excitation, no_controls, ws, xdot);
  if (o.compliant_tendons)
    for (int m = 0; m < nm; ++m)
      x[sys.fiber_length_index(m)] = muscles::compliant_equilibrium_fiber_length(
          model.muscles[m], x[sys.activation_index(m)], ws.geometry.length_m[m], ws.geometry.lengthening_speed_m_s[m]);
  // The pelvis height: pelvis_ty, or the root's fifth coordinate (OpenSim's free-joint order).
  const int height_coordinate = model.coordinate_index("pelvis_ty") >= 0 ? model.coordinate_index("pelvis_ty")
                                : root.size() > 4                        ? root[4]
                                                                         : -1;
  const double start_height = height_coordinate >= 0 ? x[height_coordinate] : 0.0;

  const std::vector<PassiveJoint> passive = passive_joints(model, o, root, ws.geometry.moment_arm_m, ws.fd.M, ref);
  // The push, as generalized forces at the interval's start.
  Eigen::VectorXd tau_push = Eigen::VectorXd::Zero(nq);
  KinematicsWorkspace<double> push_kin(model);
  MotionSubspace push_S(model);
  // A planar model (its root moves the body in the ground's x-y plane only) cannot fall sideways: its
  // centre of mass is over its feet when it lies between the loaded spheres along x.
  bool planar = true;
  {
    forward_kinematics(model, x.data(), push_kin);
    motion_subspace(model, x.data(), push_kin, push_S);
    const Eigen::Vector3d off_axis = push_kin.body_in_ground[pelvis_body].translation_m + Eigen::Vector3d::Constant(0.1);
    for (int c : root) planar = planar && std::abs(point_velocity_column(push_S, c, off_axis).z()) < 1e-9;
  }
  Eigen::VectorXd tau_root = Eigen::VectorXd::Zero(nq);  // the residuals, as generalized forces
  Eigen::MatrixXd root_columns = Eigen::MatrixXd::Zero(nq, static_cast<Eigen::Index>(root.size()));  // picks the root's
  for (std::size_t j = 0; j < root.size(); ++j) root_columns(root[j], static_cast<Eigen::Index>(j)) = 1.0;
  Eigen::VectorXd tau_extra(nq);
  // The residuals and the passive joints' torques, as generalized forces at state y.
  auto extra_forces = [&](const Eigen::VectorXd& y) -> const Eigen::VectorXd& {
    if (o.pelvis_residuals) tau_extra = tau_root + tau_push;
    else tau_extra = tau_push;
    for (const PassiveJoint& p : passive) tau_extra[p.c] -= p.stiffness * (y[p.c] - p.rest) + p.damping * y[nq + p.c];
    return tau_extra;
  };
  // They enter each evaluation's joint torques, so one solve with the mass matrix serves both.
  sys.generalized_forces = &tau_extra;
  // The integrator's evaluations skip the moment-arm matrix (MuscleGeometry::kLengthsAndSpeeds); the
  // evaluation at each control interval's start forms it for the reflexes and the Jacobian.
  auto evaluate = [&](MuscleGeometry geometry, double t, const Eigen::VectorXd& y, Eigen::VectorXd& dy) {
    extra_forces(y);
    muscle_driven_derivatives(sys, t, y, excitation, no_controls, ws, dy, geometry);
  };
  auto f = [&](double t, const Eigen::VectorXd& y, Eigen::VectorXd& dy) { evaluate(MuscleGeometry::kLengthsAndSpeeds, t, y, dy); };
  // Each control interval starts with an evaluation at (t, x) for the residuals, reflexes and records;
  // the interval's first step reuses it (its excitations changed since, so only the activation rates
  // are redone): one evaluation fewer per interval. The Jacobian is formed there once per interval and
  // serves the interval's later steps too: ROS2 keeps its order with any W (a W-method), and on
  // subject01 the steps and the motion were unchanged while the gait ran 10 % faster - measured.
  bool start_evaluation_fresh = false;
  Eigen::VectorXd xdot_start;
  auto prepare = [&](double t, const Eigen::VectorXd& y, Eigen::VectorXd& f0) {
    if (!(start_evaluation_fresh && &y == &x)) {
      f(t, y, f0);
      return;
    }
    start_evaluation_fresh = false;
    f0 = xdot_start;  // with the passive joints, without the residuals decided since
    for (int m = 0; m < nm; ++m)
      f0[sys.activation_index(m)] = thelen_activation_rate(model.muscles[m], excitation[m], y[sys.activation_index(m)]);
    muscle_driven_jacobian(sys, y, excitation, ws, jac, f0);
    if (o.pelvis_residuals) f0.segment(nq, nq) += ws.fd.llt.solve(tau_root);
    // The passive joints' spring-damper in the W matrix too: on the light toes it is stiff (damping
    // over inertia ~2,500 /s), and left explicit it bounded the step size.
    for (const PassiveJoint& p : passive) {
      jac.damping(p.c, p.c) += p.damping;
      jac.stiffness(p.c, p.c) += p.stiffness;
    }
  };
  auto w_solve = [&](double gh, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) { muscle_driven_w_solve(sys, jac, gh, rhs, k); };
  RosenbrockOptions ro;
  ro.relative_tolerance = ro.absolute_tolerance = o.integrator_tolerance;
  ro.max_step_s = o.control_interval_s;

  // Balance feedback: the legs, the reference pose's kinematics, the reference's mean pelvis velocity.
  const SimbiconLegs legs = o.balance.any() ? simbicon_legs(model, contacts) : SimbiconLegs{};
  if (o.balance.any() && !legs.valid())
    r.warnings.push_back("no balance feedback: model " + model.name + " has no hips (pelvis children named *_r, *_l) or no feet (contact spheres named *_r, *_l)");
  KinematicsWorkspace<double> reference_kin(model);
  Eigen::Vector3d pelvis_velocity_ref = Eigen::Vector3d::Zero(), pelvis_start = Eigen::Vector3d::Zero();
  {
    const double ta = ref.time_s.front(), tb = ref.time_s.back();
    Eigen::VectorXd qa(nq), qb(nq), ua(nq), aa(nq);
    trajectories_at(ref, ta, qa, ua, aa);
    trajectories_at(ref, tb, qb, ua, aa);
    forward_kinematics(model, qa.data(), reference_kin);
    const Eigen::Vector3d pa = reference_kin.body_in_ground[pelvis_body].translation_m;
    forward_kinematics(model, qb.data(), reference_kin);
    if (tb > ta) pelvis_velocity_ref = (reference_kin.body_in_ground[pelvis_body].translation_m - pa) / (tb - ta) * o.speed;
    forward_kinematics(model, x.data(), reference_kin);
    pelvis_start = reference_kin.body_in_ground[pelvis_body].translation_m;
  }
  if (o.ground_step_m != 0) {
    contacts.step_height_m = o.ground_step_m;
    contacts.step_x_m = pelvis_start.x() + (pelvis_velocity_ref.x() - contacts.ground_velocity_m_s.x()) * o.ground_step_time_s;
  }
  Eigen::VectorXd e_pelvis(static_cast<Eigen::Index>(legs.pelvis_rotations.size())), ed_pelvis(e_pelvis.size());
  // Walk -> stand: the standing pose (from the default pose, where the walk begins) the reflexes turn
  // to once the walk froze, and the joints the standing balance moves.
  const SimbiconLegs stand_legs = o.stop_time_s >= 0 ? simbicon_legs(model, contacts) : SimbiconLegs{};
  Eigen::VectorXd stand_q(nq), frozen_q(nq);
  StandingJoints stand_joints;
  if (o.stop_time_s >= 0) {
    Eigen::VectorXd q0(nq);
    for (int c = 0; c < nq; ++c) q0[c] = root_translation[static_cast<std::size_t>(c)] ? x[c] : model.coordinates[c].default_value;
    for (const PassiveJoint& p : passive) q0[p.c] = p.rest;  // where its spring holds it
    stand_q = standing_pose(model, contacts, stand_legs, q0, contacts.ground_height_m);
    forward_kinematics(model, stand_q.data(), push_kin);
    motion_subspace(model, stand_q.data(), push_kin, push_S);
    stand_joints = standing_joints(model, contacts, stand_legs, push_kin, push_S);
  }

  const double dt = o.control_interval_s;
  const int steps = static_cast<int>(std::lround(o.duration_s / dt));
  std::vector<Eigen::VectorXd> rec_q, rec_ref, rec_res, rec_exc, rec_contact;
  std::vector<double> rec_pelvis_speed;
  std::vector<char> rec_com_supported;
  Eigen::VectorXd u_in(network.size()), sig(signals.size());
  // Each sphere's foot (0 right, 1 left, -1 neither), for entrainment and the heel strikes; the resetting's state.
  std::vector<int> sphere_side;
  for (const auto& sp : contacts.spheres) sphere_side.push_back(side_of(sp.name));
  PhaseResetting resetting(o.entrainment);
  const double cycle_now_s = cpg_in.cycle_s / cpg.speed;  // the CPG's cycle at the speed knob
  // The first control interval from a time on (the stop's and the push's, as the loop finds them); the
  // interval to keep the state at (-1: none), and the one to begin at.
  auto interval_from = [dt](double t_s) { return static_cast<int>(std::ceil((t_s - 1e-9) / dt)); };
  const int checkpoint_interval = o.checkpoint_at_s >= 0 ? interval_from(o.checkpoint_at_s) : -1;
  if (checkpoint_interval >= 0 && o.stop_time_s >= 0 && checkpoint_interval > interval_from(o.stop_time_s))
    throw std::invalid_argument("reproduce_gait: a checkpoint must not follow the stop");
  int first_interval = 0;
  if (resume_from) {
    const ReproducedGaitCheckpoint& c = *resume_from;
    if (c.x.size() != x.size() || c.excitation.size() != nm || c.neurons.x.size() != neurons.x.size() || c.interval > steps ||
        std::abs(c.interval * dt - c.time_s) > 1e-9 || c.time_rec_s.size() != static_cast<std::size_t>(c.interval))
      throw std::invalid_argument("reproduce_gait: the checkpoint is not one of this model's, CPG's and control interval's walks");
    if ((o.stop_time_s >= 0 && c.interval > interval_from(o.stop_time_s)) || (o.push_time_s >= 0 && c.interval > interval_from(o.push_time_s)))
      throw std::invalid_argument("reproduce_gait: a walk resumed from a checkpoint must not stop or be pushed before it");
    first_interval = c.interval;
    x = c.x, excitation = c.excitation, neurons = c.neurons, resetting = c.resetting;
    ro.initial_step_s = c.integrator_step_s;
    r.integrator_steps = c.integrator_steps;
    r.time_s = c.time_rec_s;
    rec_q = c.q, rec_ref = c.q_reference, rec_res = c.residuals, rec_exc = c.excitations, rec_contact = c.contact_force_N;
    // Walking until the checkpoint, before any stop: what the stand's measure reads is after it.
    rec_pelvis_speed.assign(r.time_s.size(), std::numeric_limits<double>::infinity());
    rec_com_supported.assign(r.time_s.size(), 0);
    r.resumed_at_s = c.time_s;
  }
  for (int k = first_interval; k <= steps; ++k) {
    if (progress && progress->cancelled()) throw std::runtime_error("reproduced gait cancelled");
    const double t = k * dt;
    if (k == checkpoint_interval) {
      auto c = std::make_shared<ReproducedGaitCheckpoint>();
      c->interval = k, c->time_s = t;
      c->x = x, c->excitation = excitation, c->neurons = neurons, c->resetting = resetting;
      c->integrator_step_s = ro.initial_step_s;
      c->integrator_steps = r.integrator_steps;
      c->time_rec_s = r.time_s;
      c->q = rec_q, c->q_reference = rec_ref, c->residuals = rec_res, c->excitations = rec_exc, c->contact_force_N = rec_contact;
      r.checkpoint = std::move(c);
    }
    // Walk -> stand: once past stop_time_s, the walk freezes where the cycle's phase (the CPG's, or the
    // reference's by time) passes stop_phase.
    if (o.stop_time_s >= 0 && frozen_at_s < 0 && t >= o.stop_time_s - 1e-9) {
      const double cycles = (tau0 + std::min(t, tracked_until) * o.speed - o.start_time_s) / cpg_in.cycle_s;
      const double phase = o.phase_indexed_reference ? cpg_phase(phase_table, neurons, phase_nearest) : cycles - std::floor(cycles);
      const double p = o.stop_phase;
      if (phase_before >= 0 && (phase >= phase_before ? phase_before <= p && p < phase : p >= phase_before || p < phase)) frozen_at_s = t;
      phase_before = phase;
    }
    const bool frozen = frozen_at_s >= 0;
    const double tau = tau0 + std::min(frozen ? frozen_at_s : t, tracked_until) * o.speed;
    reference_at(tau, q_ref, u_ref, a_ref);
    if (o.phase_indexed_reference) phase_reference.at(cpg_phase(phase_table, neurons, phase_nearest), o.speed, root_translation, q_ref, u_ref, a_ref);
    // Standing: the share of the way from the frozen pose to the standing one (smoothstep) and its rate.
    double stand_share = 0;
    if (frozen) {
      if (t == frozen_at_s) frozen_q = q_ref;
      const double s = o.stand_blend_s > 0 ? std::min(1.0, (t - frozen_at_s) / o.stand_blend_s) : 1.0;
      stand_share = s * s * (3 - 2 * s);
      const double rate = s < 1 ? 6 * s * (1 - s) / o.stand_blend_s : 0.0;
      for (int c = 0; c < nq; ++c)
        if (!root_translation[static_cast<std::size_t>(c)]) {
          q_ref[c] = frozen_q[c] + stand_share * (stand_q[c] - frozen_q[c]);
          u_ref[c] = rate * (stand_q[c] - frozen_q[c]);
        }
      a_ref.setZero();
      contacts.ground_velocity_m_s = moving_share(t) * belt_velocity;
    }
    // The push over this interval, at the pelvis' origin now.
    tau_push.setZero();
    if (o.push_time_s >= 0 && t >= o.push_time_s - 1e-9 && t < o.push_time_s + o.push_duration_s - 1e-9) {
      forward_kinematics(model, x.data(), push_kin);
      motion_subspace(model, x.data(), push_kin, push_S);
      const Eigen::Vector3d p = push_kin.body_in_ground[pelvis_body].translation_m;
      for (int c : root) tau_push[c] = point_velocity_column(push_S, c, p).dot(o.push_force_N);
    }
    // Forces at the current state without residuals: contact, muscles, geometry for the reflexes.
    tau_root.setZero();
    evaluate(MuscleGeometry::kMomentArms, t, x, xdot);  // the passive joints' torques included
    xdot_start = xdot;
    start_evaluation_fresh = true;
    Eigen::VectorXd contact_row(3 * contacts.spheres.size());
    for (std::size_t s = 0; s < contacts.spheres.size(); ++s) {
      contact_row.segment<3>(3 * s) = ws.contact_force_N[s];
    }
    if (o.pelvis_residuals && !root.empty())  // only M^-1's root columns are needed: qdd = qdd0 + M^-1 E tau_root
      pelvis_residuals(model, root, o, ws.fd.llt.solve(root_columns), q_ref, u_ref, a_ref, x, xdot, tau_root);
    // Record.
    r.time_s.push_back(t);
    rec_q.push_back(x.head(nq));
    rec_ref.push_back(q_ref);
    Eigen::VectorXd res(root.size());
    for (std::size_t i = 0; i < root.size(); ++i) res[i] = tau_root[root[i]];
    rec_res.push_back(res);
    rec_exc.push_back(excitation);
    rec_contact.push_back(contact_row);
    if (o.stop_time_s >= 0) {
      // Standing: the pelvis' horizontal speed over the ground, the centre of mass over the support.
      const auto& kin = ws.fd.kinematics;
      const Eigen::Vector3d p = kin.body_in_ground[pelvis_body].translation_m;
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (int c : root) v += point_velocity_column(ws.fd.S, c, p) * x[nq + c];
      rec_pelvis_speed.push_back(std::hypot(v.x(), v.z()));
      rec_com_supported.push_back(centre_of_mass_supported(model, kin, ws.contact_force_N, ws.contact_point_m, planar));
    }
    if (r.fell_at_s < 0 && height_coordinate >= 0 && x[height_coordinate] < o.fall_height_fraction * start_height) {
      r.fell_at_s = t;
      break;
    }
    if (k == steps) break;
    // The CPG advances with its feedback; excitations from it and the reflexes.
    for (std::size_t i = 0; i < signals.size(); ++i) {
      if (signals[i].coordinate >= 0) {
        sig[i] = x[signals[i].coordinate];
      } else {
        double fy = 0;
        for (std::size_t s = 0; s < contacts.spheres.size(); ++s)
          if (contacts.spheres[s].body == signals[i].body) fy += ws.contact_force_N[s].y();
        sig[i] = fy > kFootContactThresholdN ? 1.0 : 0.0;
      }
    }
    u_in = signals.empty() ? Eigen::VectorXd::Zero(network.size()) : Eigen::VectorXd(cpg.feedback_gains * sig);
    double rate = 1;  // the network's rate: entrainment's time warp
    if (o.entrainment.share > 0 && !frozen) {
      double side_load[2] = {0, 0};
      for (std::size_t sp = 0; sp < contacts.spheres.size(); ++sp)
        if (sphere_side[sp] >= 0) side_load[sphere_side[sp]] += ws.contact_force_N[sp].y();
      const int side = resetting.touchdown(t, side_load[0] > kFootContactThresholdN, side_load[1] > kFootContactThresholdN, cycle_now_s);
      if (side >= 0) resetting.reset(side, cpg_phase(phase_table, neurons, phase_nearest));
      rate = resetting.rate(dt, cycle_now_s);
    }
    if (!frozen) matsuoka_step(network, neurons, rate * dt, u_in, scratch);  // frozen: it stops
    cpg_excitation_now();
    if (frozen) {
      const double keep = o.stand_fade_s > 0 ? std::max(0.0, 1 - (t - frozen_at_s) / o.stand_fade_s) : 0.0;
      for (int m = 0; m < nm; ++m) excitation[m] = model.muscles[m].min_control + keep * (excitation[m] - model.muscles[m].min_control);
    }
    if (o.reflex_kp != 0 || o.reflex_kv != 0) {
      Eigen::VectorXd e = q_ref - x.head(nq), ed = u_ref - x.segment(nq, nq);
      if (legs.valid()) {
        forward_kinematics(model, q_ref.data(), reference_kin);
        for (std::size_t i = 0; i < legs.pelvis_rotations.size(); ++i)
          e_pelvis[static_cast<Eigen::Index>(i)] = e[legs.pelvis_rotations[i]], ed_pelvis[static_cast<Eigen::Index>(i)] = ed[legs.pelvis_rotations[i]];
        SimbiconGains gains = o.balance;
        gains.trunk_kp *= 1 - stand_share, gains.trunk_kv *= 1 - stand_share;
        simbicon_balance_feedback(contacts, legs, gains, ws.fd.kinematics, ws.fd.S, x.segment(nq, nq), reference_kin, e_pelvis,
                                  ed_pelvis, moving_share(t) * pelvis_velocity_ref, ws.contact_force_N, kFootContactThresholdN, e, ed);
      }
      if (frozen) standing_balance_feedback(model, contacts, stand_legs, stand_joints, o.standing, ws.fd.kinematics, ws.fd.S, x.segment(nq, nq), 1.0, e);
      for (int c : root) e[c] = ed[c] = 0;
      const double gain = 1 + (o.stand_reflex_gain - 1) * stand_share;  // 1 while walking
      const Eigen::VectorXd drive = ws.geometry.moment_arm_m * (gain * o.reflex_kp * e + gain * o.reflex_kv * ed);
      for (int m = 0; m < nm; ++m)
        excitation[m] = std::clamp(excitation[m] + drive[m], model.muscles[m].min_control, model.muscles[m].max_control);
    }
    const auto s = integrate_w_method(o.integrator, f, prepare, w_solve, t, t + dt, x, ro);
    ro.initial_step_s = s.last_step_s;
    r.integrator_steps += s.accepted_steps;
    if (!s.success || !x.allFinite()) {
      r.warnings.push_back("the simulation stopped at " + std::to_string(t) + " s: " + (s.success ? "the state is not finite" : s.message));
      r.fell_at_s = t;
      break;
    }
    if (progress) progress->report(double(k + 1) / steps, "reproduced gait");
  }

  r.entrainment = o.entrainment;
  r.entrainment_resets = resetting.touchdowns();
  // Tables and metrics.
  const int ns = static_cast<int>(r.time_s.size());
  r.q.resize(ns, nq);
  r.q_reference.resize(ns, nq);
  r.residuals.resize(ns, root.size());
  r.excitations.resize(ns, nm);
  r.contact_force_N.resize(ns, 3 * contacts.spheres.size());
  for (int i = 0; i < ns; ++i) {
    r.q.row(i) = rec_q[i].transpose();
    r.q_reference.row(i) = rec_ref[i].transpose();
    r.residuals.row(i) = rec_res[i].transpose();
    r.excitations.row(i) = rec_exc[i].transpose();
    r.contact_force_N.row(i) = rec_contact[i].transpose();
  }
  r.frozen_at_s = frozen_at_s;
  WalkRecord record;
  record.root = &root, record.sphere_side = &sphere_side;
  record.cycle_s = cpg_in.cycle_s, record.speed = cpg_in.speed * o.speed;
  record.tracked_until_s = tracked_until, record.dt_s = dt, record.belt_velocity_m_s = belt_velocity;
  record.pelvis_speed_m_s = &rec_pelvis_speed, record.com_supported = &rec_com_supported;
  record.residuals = o.pelvis_residuals;
  measure_walk(model, record, r);
  r.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return r;
}

double reproduced_gait_begin_s(const CpgModel& cpg, double reference_front_s, double reference_end_s, const ReproducedGaitOptions& o) {
  if (o.begin_time_s >= 0) return o.begin_time_s;
  const double at_cpg_start = o.start_time_s + cpg.phase_at_start * cpg.cycle_s;
  // Earlier rather than run past the trial.
  if (at_cpg_start + o.duration_s * o.speed > reference_end_s) return std::max(reference_front_s, reference_end_s - o.duration_s * o.speed);
  return at_cpg_start;
}

ReproducedGaitOptions with_controller(const CpgController& c, ReproducedGaitOptions o) {
  o.reflex_kp = c.reflex_kp;
  o.reflex_kv = c.reflex_kv;
  o.phase_indexed_reference = c.phase_reference;
  o.pelvis_residuals = c.pelvis_residuals;
  o.balance = {c.trunk_kp, c.trunk_kv, c.lateral_d, c.lateral_v, c.sagittal_d, c.sagittal_v, c.stance_lateral_d, c.stance_lateral_v, c.ankle_d, c.ankle_v, c.swing_world};
  o.entrainment.share = c.entrainment;
  o.entrainment.phase_r = c.entrainment_phase_r;
  o.entrainment.phase_l = c.entrainment_phase_l;
  if (c.start_time_s >= 0) o.start_time_s = c.start_time_s;
  if (c.begin_time_s >= 0) o.begin_time_s = c.begin_time_s;
  return with_controller_simulation(c, o);
}

ReproducedGaitOptions with_controller_simulation(const CpgController& c, ReproducedGaitOptions o) {
  if (c.control_interval_s > 0) o.control_interval_s = c.control_interval_s;
  if (c.integrator_tolerance > 0) o.integrator_tolerance = c.integrator_tolerance;
  if (const auto method = w_method_named(c.integrator)) o.integrator = *method;
  return o;
}

void record_simulation(const ReproducedGaitOptions& o, CpgController& c) {
  c.control_interval_s = o.control_interval_s;
  c.integrator_tolerance = o.integrator_tolerance;
  c.integrator = w_method_name(o.integrator);
}

std::string ReproducedGaitResult::BriefReport() const {
  char buf[500];
  std::snprintf(buf, sizeof buf,
                "Gait: %.2f s simulated in %.2f s (%.1fx real time, %ld integrator steps); %zu right and %zu left heel strikes; stride %.3f s, "
                "%.3f m, %.2f m/s; worst rotation RMS vs reference %s %.2f deg; pelvis residual force %.1f %% BW, moment "
                "%.1f N m; %s",
                time_s.empty() ? 0.0 : time_s.back(), solve_seconds, real_time_factor(), integrator_steps, heel_strikes_r_s.size(),
                heel_strikes_l_s.size(), stride_time_s, stride_length_m, speed_m_s, worst_rotation.c_str(),
                worst_rotation_rms_rad * 180 / M_PI, mean_residual_force_percent_bw, mean_residual_moment_Nm,
                fell_at_s >= 0 ? ("fell at " + std::to_string(fell_at_s) + " s after " + std::to_string(distance_m) + " m").c_str()
                               : ("walked " + std::to_string(distance_m) + " m").c_str());
  std::string out = buf;
  if (stride_time_s > 0) {
    std::snprintf(buf, sizeof buf, "; stance %.0f / %.0f %% (right / left), double support %.0f %%, flight %.0f %%", stance_percent_r,
                  stance_percent_l, double_support_percent, flight_percent);
    out += buf;
  }
  if (frozen_at_s >= 0) {
    std::snprintf(buf, sizeof buf, "; froze at %.2f s", frozen_at_s);
    out += buf;
  }
  if (stopped_at_s >= 0) {
    std::snprintf(buf, sizeof buf, ", came to rest at %.2f s and stood %.2f s with the centre of mass over the feet", stopped_at_s, stood_s);
    out += buf;
  }
  return out;
}

Storage reproduced_gait_motion_table(const Model& model, const ReproducedGaitResult& r) {
  return make_storage("ReproducedGait", r.coordinate_names, r.time_s, coordinates_in_file_units(model, r.q), true);
}

Storage reproduced_gait_residual_table(const ReproducedGaitResult& r) {
  return make_storage("PelvisResiduals", r.residual_names, r.time_s, r.residuals, false);
}

Storage reproduced_gait_contact_table(const ReproducedGaitResult& r) {
  std::vector<std::string> names;
  for (const auto& s : r.contact_names)
    for (const char* a : {"_force_x", "_force_y", "_force_z"}) names.push_back(s + a);
  return make_storage("ContactForces", names, r.time_s, r.contact_force_N, false);
}

nlohmann::json reproduced_gait_contact_phases(const ReproducedGaitResult& r) {
  return {{"stance_percent", {{"right", r.stance_percent_r}, {"left", r.stance_percent_l}}},
          {"double_support_percent", r.double_support_percent},
          {"flight_percent", r.flight_percent}};
}

nlohmann::json reproduced_gait_metrics(const Model& model, const ReproducedGaitResult& r) {
  nlohmann::json j;
  j["simulated_s"] = r.time_s.empty() ? 0.0 : r.time_s.back();
  j["reference_begin_s"] = r.reference_begin_s;
  j["real_time_factor"] = r.real_time_factor();
  j["heel_strikes_s"] = {{"right", r.heel_strikes_r_s}, {"left", r.heel_strikes_l_s}};
  j["stride_time_s"] = r.stride_time_s;
  j["stride_length_m"] = r.stride_length_m;
  j["speed_m_s"] = r.speed_m_s;
  j["distance_m"] = r.distance_m;
  j["drift_rad"] = r.drift_rad;
  j["cycle_change_rad"] = r.cycle_change_rad;
  j["contact_phases"] = reproduced_gait_contact_phases(r);
  if (r.entrainment.share > 0)
    j["entrainment"] = {{"share", r.entrainment.share}, {"phase_r", r.entrainment.phase_r}, {"phase_l", r.entrainment.phase_l}, {"resets", r.entrainment_resets}};
  if (r.frozen_at_s >= 0) j["stand"] = {{"frozen_at_s", r.frozen_at_s}, {"stopped_at_s", r.stopped_at_s >= 0 ? nlohmann::json(r.stopped_at_s) : nlohmann::json(nullptr)}, {"stood_s", r.stood_s}};
  j["fell_at_s"] = r.fell_at_s >= 0 ? nlohmann::json(r.fell_at_s) : nlohmann::json(nullptr);
  j["pelvis_residual_force_percent_bw"] = r.mean_residual_force_percent_bw;
  j["pelvis_residual_moment_Nm"] = r.mean_residual_moment_Nm;
  nlohmann::json rms = nlohmann::json::object();
  for (int c = 0; c < model.num_coordinates(); ++c)
    rms[r.coordinate_names[c]] = model.coordinates[c].is_angle() ? r.tracking_rms[c] * 180 / M_PI : r.tracking_rms[c];
  j["tracking_rms_deg_or_m"] = rms;
  nlohmann::json first = nlohmann::json::object();
  for (int c = 0; c < model.num_coordinates(); ++c)
    first[r.coordinate_names[c]] = r.tracking_rms_first_two_cycles[c] * (model.coordinates[c].is_angle() ? 180 / M_PI : 1.0);
  j["tracking_rms_first_two_cycles_deg_or_m"] = first;
  j["warnings"] = r.warnings;
  return j;
}

}  // namespace cpgait
