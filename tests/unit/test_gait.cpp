// The reproduced gait's bookkeeping on the fixture walker (the subject01 figures are in
// reference/test_so_gait2392.cpp): where in the reference it begins, and the CPG's phase there.
#include <gtest/gtest.h>

#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/cpg/matsuoka.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/gait/simbicon_balance.h"
#include "cpgait/gait/tune_gait_controller.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/capture/input_error.h"
#include "test_support.h"

using namespace cpgait;

namespace {

// A two-neuron CPG driving every muscle of the model, its start state on the limit cycle.
CpgModel walker_cpg(const Model& m) {
  CpgModel c;
  c.network = MatsuokaNetwork::pair(5.0, 0.05, 0.5, 2.5, 1.5, 1.5);
  c.network.s[1] = 5.0;
  const int nm = static_cast<int>(m.muscles.size());
  for (const auto& mu : m.muscles) c.muscle_names.push_back(mu.name);
  c.output_map = Eigen::MatrixXd::Zero(nm, 2);
  for (int k = 0; k < nm; ++k) c.output_map(k, k % 2) = 0.05 + 0.01 * k;
  c.output_bias = Eigen::VectorXd::Zero(nm);
  c.feedback_gains = Eigen::MatrixXd::Zero(2, 0);
  c.start = MatsuokaState::resting(c.network);
  const double dt = 0.001;
  const CpgRun settle = run_cpg(c, 20.0, dt);
  c.cycle_s = oscillation_period(settle.neurons.col(0), dt, 0);
  MatsuokaState s = c.start;
  simulate_matsuoka(c.network, s, dt, 20000, Eigen::MatrixXd());
  c.start = s;
  return c;
}

}  // namespace

TEST(ReproducedGait, BeginsAnywhereWithTheCpgAtTheReferencesPhase) {
  const Model& m = refdata::walker();
  const CpgModel cpg = walker_cpg(m);
  ASSERT_GT(cpg.cycle_s, 0.2);
  // The reference: the default pose held for 3 s.
  std::vector<double> t;
  for (int i = 0; i <= 300; ++i) t.push_back(0.01 * i);
  Eigen::MatrixXd q = m.default_coordinates().transpose().replicate(static_cast<Eigen::Index>(t.size()), 1);
  const Storage reference = make_storage("still", coordinate_names(m), t, q, false);
  ContactSet feet = default_foot_contacts(m);
  place_ground_under_feet(m, feet, t, q);
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;  // the CPG's start state belongs here
  o.duration_s = 0.01;
  o.reflex_kp = o.reflex_kv = 0;  // excitations: the CPG's alone
  const double dt = o.control_interval_s;

  // Begun 0.3 cycles later: the CPG is where it would be after 0.3 cycles.
  o.begin_time_s = o.start_time_s + 0.3 * cpg.cycle_s;
  const ReproducedGaitResult later = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_DOUBLE_EQ(later.reference_begin_s, o.begin_time_s);
  const CpgRun run = run_cpg(cpg, 0.3 * cpg.cycle_s, dt);
  const Eigen::VectorXd expected = run.excitations.bottomRows(1).transpose();
  EXPECT_LT((later.excitations.row(0).transpose() - expected).cwiseAbs().maxCoeff(), 1e-9);
  // ... and not where it starts (so the comparison above could fail).
  o.begin_time_s = -1;
  const ReproducedGaitResult at_start = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_DOUBLE_EQ(at_start.reference_begin_s, o.start_time_s);
  EXPECT_GT((at_start.excitations.row(0) - later.excitations.row(0)).cwiseAbs().maxCoeff(), 0.01);

  // A simulation that would run past the reference's end begins earlier instead, the CPG with it.
  o.start_time_s = 2.0;
  o.duration_s = 1.5;
  const ReproducedGaitResult early = reproduce_gait(m, cpg, reference, feet, o);
  EXPECT_NEAR(early.reference_begin_s, 1.5, 1e-12);
  for (const auto& w : early.warnings) {
    EXPECT_EQ(w.find("reference kinematics end"), std::string::npos) << w;
  }
  // A begin outside the reference is refused, naming the field.
  o.begin_time_s = 3.5;
  try {
    reproduce_gait(m, cpg, reference, feet, o);
    ADD_FAILURE() << "a begin after the reference's end was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "begin_time");
  }
}

namespace {

// The walker in a walking-like pose: hips, knees and pelvis off their defaults so no Jacobian is special.
Eigen::VectorXd walker_pose(const Model& m) {
  Eigen::VectorXd q = m.default_coordinates();
  const std::pair<const char*, double> set[] = {{"pelvis_tilt", 0.1},     {"pelvis_list", -0.05},    {"pelvis_rotation", 0.2},
                                                {"hip_flexion_r", 0.4},   {"hip_adduction_r", 0.05}, {"hip_rotation_r", 0.1},
                                                {"knee_angle_r", -0.6},   {"hip_flexion_l", -0.2},   {"hip_adduction_l", -0.04},
                                                {"hip_rotation_l", -0.1}, {"knee_angle_l", -0.2}};
  for (const auto& [name, value] : set) q[m.coordinate_index(name)] = value;
  return q;
}

struct BalanceCase {
  const Model& m = refdata::walker();
  ContactSet feet = default_foot_contacts(m);
  SimbiconLegs legs = simbicon_legs(m, feet);
  Eigen::VectorXd q = walker_pose(m);
  KinematicsWorkspace<double> kin{m};
  MotionSubspace S{m};
  BalanceCase() {
    forward_kinematics(m, q.data(), kin);
    motion_subspace(m, q.data(), kin, S);
  }
  // Right foot on the ground (body weight), left in the air.
  std::vector<Eigen::Vector3d> right_stance() const {
    std::vector<Eigen::Vector3d> f(feet.spheres.size(), Eigen::Vector3d::Zero());
    for (int s : legs.spheres[0]) f[s] = Eigen::Vector3d(0, 400, 0);
    return f;
  }
};

Eigen::Vector3d mean_sphere_centre(const BalanceCase& c, const KinematicsWorkspace<double>& kin, int side) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int s : c.legs.spheres[side]) p += kin.body_in_ground[c.feet.spheres[s].body].rotation * c.feet.spheres[s].location_m +
                                          kin.body_in_ground[c.feet.spheres[s].body].translation_m;
  return p / static_cast<double>(c.legs.spheres[side].size());
}

}  // namespace

// Trunk balance: the stance hip's target change, made together with the pelvis' correction, leaves the
// stance femur where it was (to first order), so it is the hip motion that rights the pelvis about a
// planted leg; the swing hip gets none of it.
TEST(SimbiconBalance, StanceHipTargetTurnsThePelvisAboutTheStillFemur) {
  BalanceCase c;
  ASSERT_TRUE(c.legs.valid());
  ASSERT_EQ(c.legs.pelvis_rotations.size(), 3u);
  ASSERT_EQ(c.legs.hip[0].size(), 3u);
  const int nq = c.m.num_coordinates();
  SimbiconGains g;
  g.trunk_kp = 1.0;
  const double h = 1e-4;
  const Eigen::Vector3d e_pelvis = h * Eigen::Vector3d(1.0, -0.7, 0.4);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(nq), ed = Eigen::VectorXd::Zero(nq);
  simbicon_balance_feedback(c.feet, c.legs, g, c.kin, c.S, Eigen::VectorXd::Zero(nq), c.kin, e_pelvis, Eigen::Vector3d::Zero(),
                            Eigen::Vector3d::Zero(), c.right_stance(), 20.0, e, ed);
  for (int k : c.legs.hip[1]) EXPECT_EQ(e[k], 0.0) << "the swing hip";
  EXPECT_GT(e(c.legs.hip[0]).norm(), 0.5 * h);
  Eigen::VectorXd moved = c.q;
  for (int i = 0; i < 3; ++i) moved[c.legs.pelvis_rotations[i]] += e_pelvis[i];
  for (int k : c.legs.hip[0]) moved[k] += e[k];
  KinematicsWorkspace<double> after(c.m);
  forward_kinematics(c.m, moved.data(), after);
  const int femur = c.m.body_index("femur_r");
  const Eigen::AngleAxisd turn(after.body_in_ground[femur].rotation * c.kin.body_in_ground[femur].rotation.transpose());
  EXPECT_LT(turn.angle(), 1e-3 * h) << "the stance femur turned by " << turn.angle() << " rad for a pelvis correction of " << h;
  // Without the hip's change, the femur would turn with the pelvis.
  moved = c.q;
  for (int i = 0; i < 3; ++i) moved[c.legs.pelvis_rotations[i]] += e_pelvis[i];
  forward_kinematics(c.m, moved.data(), after);
  EXPECT_GT(Eigen::AngleAxisd(after.body_in_ground[femur].rotation * c.kin.body_in_ground[femur].rotation.transpose()).angle(), 0.5 * h);
}

// Foot placement: the swing hip's target change moves the swing foot by c_v (v - v_ref) across the
// walking direction and c_d (d - d_ref) along it (to first order), without turning the thigh about
// its axis; the stance hip gets none of it.
TEST(SimbiconBalance, SwingHipTargetMovesTheFootByTheRaibertShift) {
  BalanceCase c;
  const int nq = c.m.num_coordinates();
  SimbiconGains g;
  g.lateral_v = 0.2;
  g.sagittal_d = 0.5;
  const double h = 1e-4;
  // The state: the pelvis moving sideways faster than the reference; the reference pose: the stance
  // hip flexed a little more, so the pelvis' offset from the stance foot differs.
  Eigen::VectorXd u = Eigen::VectorXd::Zero(nq);
  u[c.m.coordinate_index("pelvis_tz")] = h / g.lateral_v;  // ground z
  Eigen::VectorXd q_ref = c.q;
  q_ref[c.m.coordinate_index("hip_flexion_r")] += h;
  KinematicsWorkspace<double> ref_kin(c.m);
  forward_kinematics(c.m, q_ref.data(), ref_kin);
  const int pelvis = c.legs.pelvis_body;
  const Eigen::Vector3d d_error = (c.kin.body_in_ground[pelvis].translation_m - mean_sphere_centre(c, c.kin, 0)) -
                                  (ref_kin.body_in_ground[pelvis].translation_m - mean_sphere_centre(c, ref_kin, 0));
  Eigen::VectorXd e = Eigen::VectorXd::Zero(nq), ed = Eigen::VectorXd::Zero(nq);
  simbicon_balance_feedback(c.feet, c.legs, g, c.kin, c.S, u, ref_kin, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                            Eigen::Vector3d::Zero(), c.right_stance(), 20.0, e, ed);
  for (int k : c.legs.hip[0]) EXPECT_EQ(e[k], 0.0) << "the stance hip";
  EXPECT_EQ(e[c.m.coordinate_index("hip_rotation_l")], 0.0) << "the thigh's twist";
  Eigen::VectorXd moved = c.q;
  for (int k : c.legs.hip[1]) moved[k] += e[k];
  KinematicsWorkspace<double> after(c.m);
  forward_kinematics(c.m, moved.data(), after);
  const Eigen::Vector3d shift = mean_sphere_centre(c, after, 1) - mean_sphere_centre(c, c.kin, 1);
  // The reference pelvis' heading: its x axis, horizontal (pelvis_rotation turns it about y).
  Eigen::Vector3d along = ref_kin.body_in_ground[c.legs.pelvis_body].rotation.col(0);
  along.y() = 0;
  along.normalize();
  const Eigen::Vector3d across = along.cross(Eigen::Vector3d::UnitY());
  const Eigen::Vector3d want = along * (g.sagittal_d * d_error.dot(along)) + across * (g.lateral_v * u[c.m.coordinate_index("pelvis_tz")] * across.z());
  EXPECT_GT(std::abs(d_error.dot(along)), 0.1 * h);
  EXPECT_NEAR(shift.x(), want.x(), 1e-3 * h);
  EXPECT_NEAR(shift.z(), want.z(), 1e-3 * h);
  EXPECT_GT(shift.norm(), 0.5 * h);
}

namespace {

// The walker's reference: the default pose held for 3 s, and its CPG; the gait starts at 0.5 s.
struct StillWalker {
  const Model& m = refdata::walker();
  CpgModel cpg = walker_cpg(m);
  std::vector<double> t;
  Storage reference;
  ContactSet feet = default_foot_contacts(m);
  StillWalker() {
    for (int i = 0; i <= 300; ++i) t.push_back(0.01 * i);
    const Eigen::MatrixXd q = m.default_coordinates().transpose().replicate(static_cast<Eigen::Index>(t.size()), 1);
    reference = make_storage("still", coordinate_names(m), t, q, false);
    place_ground_under_feet(m, feet, t, q);
  }
  Eigen::Vector3d centre_of_mass(const Eigen::VectorXd& q) const {
    KinematicsWorkspace<double> k(m);
    forward_kinematics(m, q.data(), k);
    return centre_of_mass_m(m, k);
  }
};

}  // namespace

// A push at the pelvis moves the centre of mass as its impulse would: in the air (the ground far
// below), only gravity and the push act on the body as a whole, so with and without it the centre of
// mass parts by F/M (d^2/2 + d (T - t_push - d)) along the push.
TEST(ReproducedGait, PushMovesTheCentreOfMassByItsImpulse) {
  StillWalker w;
  w.feet.ground_height_m -= 10.0;
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;
  o.duration_s = 0.3;
  o.reflex_kp = 50;  // the muscles busy: they move the segments, not the centre of mass
  o.reflex_kv = 5;
  o.pelvis_residuals = false;
  o.fall_height_fraction = -1e9;  // falling is the point here
  const ReproducedGaitResult free = reproduce_gait(w.m, w.cpg, w.reference, w.feet, o);
  o.push_time_s = 0.1;
  o.push_duration_s = 0.05;
  o.push_force_N = Eigen::Vector3d(300, 0, -200);
  const ReproducedGaitResult pushed = reproduce_gait(w.m, w.cpg, w.reference, w.feet, o);
  ASSERT_EQ(free.time_s.size(), pushed.time_s.size());
  const Eigen::Index last = static_cast<Eigen::Index>(free.time_s.size()) - 1;
  const double T = free.time_s.back(), d = o.push_duration_s;
  const Eigen::Vector3d apart = w.centre_of_mass(pushed.q.row(last).transpose()) - w.centre_of_mass(free.q.row(last).transpose());
  const Eigen::Vector3d want = o.push_force_N / w.m.total_mass_kg() * (0.5 * d * d + d * (T - o.push_time_s - d));
  EXPECT_LT((apart - want).norm(), 0.01 * want.norm()) << "apart " << apart.transpose() << ", want " << want.transpose();
  // Before the push the two are the same.
  const Eigen::Index before = static_cast<Eigen::Index>(std::lround(0.09 / o.control_interval_s));
  EXPECT_LT((pushed.q.row(before) - free.q.row(before)).cwiseAbs().maxCoeff(), 1e-12);
}

// The ground's step: the ground is step_height_m higher past its edge, the edge carried by the belt.
TEST(ContactSet, StepEdgeRidesOnTheBelt) {
  ContactSet set;
  set.ground_height_m = 0.02;
  set.ground_velocity_m_s = Eigen::Vector3d(-1.2, 0, 0);
  set.step_height_m = -0.03;
  set.step_x_m = 0.5;
  EXPECT_NEAR(ground_height_at(set, 0.0, 0.0), 0.02, 1e-12);
  EXPECT_NEAR(ground_height_at(set, 1.0, 0.0), -0.01, 1e-12);
  EXPECT_NEAR(ground_height_at(set, 0.5, 0.0), 0.005, 1e-12);  // halfway down at the edge
  // After 1 s the edge has moved 1.2 m back with the belt.
  EXPECT_NEAR(ground_height_at(set, -0.7, 1.0), 0.005, 1e-12);
  EXPECT_NEAR(ground_height_at(set, 0.0, 1.0), -0.01, 1e-12);
  // A sphere at rest on the upper level, moved over the lower one, is clear of the ground.
  ContactSphere s;
  EXPECT_GT(sphere_contact_force(s, set, Eigen::Vector3d(0.0, 0.02 + s.radius_m - 0.001, 0), Eigen::Vector3d::Zero(), 0.0).y(), 10.0);
  EXPECT_LT(sphere_contact_force(s, set, Eigen::Vector3d(1.0, 0.02 + s.radius_m - 0.001, 0), Eigen::Vector3d::Zero(), 0.0).norm(), 1e-6);
}

// Walk -> stand: past stop_time_s the walk goes on to the stop phase, then freezes: the reference
// pose stays that of the stop phase, at rest, and the CPG's excitations hold (no reflexes here).
//
// The stop was chosen on gait10dof18musc (tuned controller, stop from 4.5 s, 12 s; measured): frozen
// at phase 0.8 it fell at 8.0 s and at 0.85 at 7.1 s; at 0.9, 0.95 and 0.0 it came to rest within
// 0.5-1 s and stood to the end; at 0.05 it came to rest only at 10.45 s. The stop before it faded the
// CPG out and turned the reflexes' targets to the cycle's mean pose: gait10dof18musc came to rest on
// its toes and tipped over about 4 s later; subject01 fell 1-1.6 s after the stop. subject01 still
// falls, sideways, 1.3-2 s after a freeze at every phase tried (0, 0.03, 0.06, 0.1, 0.5, 0.53, 0.56,
// 0.9, 0.95), with the CPG's excitations held or halved.
TEST(ReproducedGait, StopFreezesTheWalkAtItsStopPhase) {
  StillWalker w;
  const int nq = w.m.num_coordinates();
  // A reference that moves: the hip swings once a CPG cycle.
  Eigen::MatrixXd q = w.m.default_coordinates().transpose().replicate(static_cast<Eigen::Index>(w.t.size()), 1);
  const int hip = w.m.coordinate_index("hip_flexion_r");
  for (std::size_t i = 0; i < w.t.size(); ++i) q(static_cast<Eigen::Index>(i), hip) = 0.3 + 0.2 * std::sin(2 * M_PI * w.t[i] / w.cpg.cycle_s);
  const Storage reference = make_storage("swing", coordinate_names(w.m), w.t, q, false);
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;
  o.begin_time_s = 0.5;
  o.duration_s = 0.5;
  o.reflex_kp = o.reflex_kv = 0;
  o.stop_time_s = 0.1;
  o.stop_phase = 0.4;
  const ReproducedGaitResult r = reproduce_gait(w.m, w.cpg, reference, w.feet, o);
  ASSERT_GT(r.time_s.size(), 400u);
  // The phase reaches 0.4 at 0.4 cycles after the start's heel strike (at the beginning here).
  const double dt = o.control_interval_s;
  EXPECT_NEAR(r.frozen_at_s, 0.4 * w.cpg.cycle_s, dt + 1e-9);
  const Eigen::Index frozen = static_cast<Eigen::Index>(std::lround(r.frozen_at_s / dt));
  const Eigen::Index walking = frozen / 2, last = static_cast<Eigen::Index>(r.time_s.size()) - 1;
  // The hip's target: the reference at the stop phase, from the freeze to the end.
  const double at_stop = 0.3 + 0.2 * std::sin(2 * M_PI * (o.start_time_s / w.cpg.cycle_s + 0.4));
  EXPECT_NEAR(r.q_reference(last, hip), at_stop, 0.2 * 2 * M_PI * dt / w.cpg.cycle_s);
  EXPECT_GT(std::abs(r.q_reference(walking, hip) - r.q_reference(last, hip)), 0.01);
  EXPECT_LT((r.q_reference.row(last) - r.q_reference.row(frozen + 1)).cwiseAbs().maxCoeff(), 1e-12);
  // The CPG's excitations: moving before the freeze, held after it.
  EXPECT_GT((r.excitations.row(walking) - r.excitations.row(frozen - 1)).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_LT((r.excitations.row(last) - r.excitations.row(frozen + 1)).cwiseAbs().maxCoeff(), 1e-12);
  for (int c = 0; c < nq; ++c) {
    if (c != hip && w.m.coordinates[c].is_angle()) {
      EXPECT_NEAR(r.q_reference(last, c), q(0, c), 1e-9) << w.m.coordinates[c].name;
    }
  }
}

// The tuner's extra walks and bound enter each candidate's cost: a ground step of zero height is the
// level walk again (the cost unchanged), a bound on the worst rotation far above it changes nothing,
// one far below it costs more than a fall.
TEST(GaitTuning, GroundStepsAndTheRotationBoundEnterTheCost) {
  StillWalker w;
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;
  GaitTuningOptions t;
  t.evaluations = 2;
  t.horizon_s = 0.3;
  t.num_threads = 1;
  const double level = tune_gait_controller(w.m, w.cpg, w.reference, w.feet, o, t).summary.start_cost;
  GaitTuningOptions flat_step = t;
  flat_step.ground_steps_m = {0.0};
  EXPECT_NEAR(tune_gait_controller(w.m, w.cpg, w.reference, w.feet, o, flat_step).summary.start_cost, level, 1e-12);
  GaitTuningOptions loose = t, tight = t;
  loose.worst_rotation_limit_deg = 1e6;
  tight.worst_rotation_limit_deg = 1e-6;
  EXPECT_NEAR(tune_gait_controller(w.m, w.cpg, w.reference, w.feet, o, loose).summary.start_cost, level, 1e-12);
  EXPECT_GT(tune_gait_controller(w.m, w.cpg, w.reference, w.feet, o, tight).summary.start_cost, level + t.fall_weight);
}

// Joints no muscle crosses (the walker's back) are held at the trial's mean as a locked joint would
// be; before, nothing held them and the torso fell about its joint.
TEST(ReproducedGait, UnmuscledJointsAreHeldAtTheTrialsMean) {
  StillWalker w;
  Eigen::MatrixXd q = w.m.default_coordinates().transpose().replicate(static_cast<Eigen::Index>(w.t.size()), 1);
  const int back = w.m.coordinate_index("lumbar_extension");
  for (std::size_t i = 0; i < w.t.size(); ++i) q(static_cast<Eigen::Index>(i), back) = 0.2 + (i < w.t.size() / 2 ? 0.05 : -0.05);
  const Storage reference = make_storage("leaning", coordinate_names(w.m), w.t, q, false);
  ReproducedGaitOptions o;
  o.start_time_s = 0.5;
  o.duration_s = 1.0;
  o.amplitude = 0;                // the muscles at rest: the walker sags (the pelvis on its soft springs) ...
  o.fall_height_fraction = -1e9;  // ... which does not matter here
  const ReproducedGaitResult r = reproduce_gait(w.m, w.cpg, reference, w.feet, o);
  for (Eigen::Index i = r.q.rows() / 2; i < r.q.rows(); ++i) {
    ASSERT_NEAR(r.q(i, back), 0.2, 0.01) << "at " << r.time_s[static_cast<std::size_t>(i)] << " s";
  }
}
