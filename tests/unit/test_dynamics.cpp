#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <utility>

#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/applied_loads.h"
#include "cpgait/dynamics/articulated_body.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/dynamics/forward_dynamics.h"
#include <Eigen/Eigenvalues>
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/rnea.h"
#include "cpgait/dynamics/tree_cholesky.h"
#include "cpgait/dynamics/tree_lu.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/signal/lowpass.h"
#include "test_support.h"

using namespace cpgait;

namespace {

using refdata::walker;

// Energies computed independently of RNEA: body velocities from the motion subspace.
double kinetic_energy(const Model& m, const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  forward_kinematics(m, q.data(), ws);
  motion_subspace(m, q.data(), ws, S);
  double T = 0;
  for (std::size_t b = 1; b < m.bodies.size(); ++b) {
    Vector6d V = Vector6d::Zero();
    for (int c : ancestor_coordinates(m, static_cast<int>(b))) V += S.columns.col(c) * qd[c];
    const auto& X = ws.body_in_ground[b];
    const Eigen::Vector3d c = X.rotation * m.bodies[b].com_m + X.translation_m;
    const Eigen::Vector3d w = V.head<3>(), v = V.tail<3>() + w.cross(c);
    T += 0.5 * m.bodies[b].mass_kg * v.squaredNorm() +
         0.5 * w.dot(X.rotation * m.bodies[b].inertia_kg_m2 * X.rotation.transpose() * w);
  }
  return T;
}

double potential_energy(const Model& m, const Eigen::VectorXd& q) {
  KinematicsWorkspace<double> ws(m);
  forward_kinematics(m, q.data(), ws);
  double V = 0;
  for (std::size_t b = 1; b < m.bodies.size(); ++b) {
    const auto& X = ws.body_in_ground[b];
    V -= m.bodies[b].mass_kg * m.gravity_m_s2.dot(X.rotation * m.bodies[b].com_m + X.translation_m);
  }
  return V;
}

Eigen::VectorXd random_vector(int n, std::mt19937& rng, double scale) {
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = std::uniform_real_distribution<double>(-scale, scale)(rng);
  return v;
}

Eigen::VectorXd rnea_tau(const Model& m, const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& qdd,
                         const std::vector<Vector6d>& ext = {}) {
  DynamicsWorkspace ws(m);
  Eigen::VectorXd tau(m.num_coordinates());
  rnea(m, q.data(), qd.data(), qdd.data(), ext, ws, tau.data());
  return tau;
}

}  // namespace

// tau = d/dt dT/dqd - dT/dq + dV/dq, by finite differences of the energies: checks velocities,
// accelerations (including dS/dt of the knee's coupled translations), inertia and gravity at once.
TEST(Rnea, MatchesLagrangesEquations) {
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(11);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = random_vector(n, rng, 0.6), qd = random_vector(n, rng, 2.0), qdd = random_vector(n, rng, 5.0);
    const Eigen::VectorXd tau = rnea_tau(m, q, qd, qdd);
    auto dT_dqd = [&](const Eigen::VectorXd& qq, const Eigen::VectorXd& vv) {
      Eigen::VectorXd g(n);
      for (int c = 0; c < n; ++c) {
        Eigen::VectorXd a = vv, b = vv;
        a[c] += 1e-3;
        b[c] -= 1e-3;
        g[c] = (kinetic_energy(m, qq, a) - kinetic_energy(m, qq, b)) / 2e-3;  // T is quadratic in qd
      }
      return g;
    };
    const double h = 1e-5;
    const Eigen::VectorXd ddt = (dT_dqd(q + qd * h + 0.5 * qdd * h * h, qd + qdd * h) -
                                 dT_dqd(q - qd * h + 0.5 * qdd * h * h, qd - qdd * h)) / (2 * h);
    Eigen::VectorXd expected(n);
    for (int c = 0; c < n; ++c) {
      Eigen::VectorXd a = q, b = q;
      a[c] += 1e-6;
      b[c] -= 1e-6;
      expected[c] = ddt[c] - (kinetic_energy(m, a, qd) - kinetic_energy(m, b, qd)) / 2e-6 +
                    (potential_energy(m, a) - potential_energy(m, b)) / 2e-6;
    }
    for (int c = 0; c < n; ++c)
      EXPECT_NEAR(tau[c], expected[c], 1e-4 * (1 + std::abs(expected[c]))) << m.coordinates[c].name;
  }
}

// S and dS/dt from motion_subspace_and_rate (each column turned by its parent's velocity and by its
// joint's own rotations, plus its functions' second derivatives) are what motion_subspace on a Jet
// carrying qd gives down the whole tree; and the two-part RNEA is RNEA.
void expect_rate_is_the_jet_pass(const Model& m, std::mt19937& rng, const std::string& what) {
  const int n = m.num_coordinates();
  using Jet = ceres::Jet<double, 1>;
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = random_vector(n, rng, 0.5), qd = random_vector(n, rng, 3.0);
    DynamicsWorkspace dyn(m);
    rnea_kinematics(m, q.data(), qd.data(), dyn);
    std::vector<Jet> q_jet(n);
    for (int c = 0; c < n; ++c) q_jet[c] = Jet(q[c], 0), q_jet[c].v[0] = qd[c];
    KinematicsWorkspace<Jet> kin(m);
    MotionSubspaceT<Jet> S(m);
    forward_kinematics(m, q_jet.data(), kin);
    motion_subspace(m, q_jet.data(), kin, S);
    double worst = 0, scale = 1;
    for (int c = 0; c < n; ++c)
      for (int r = 0; r < 6; ++r) {
        worst = std::max(worst, std::abs(dyn.S_rate(r, c) - S.columns(r, c).v[0]));
        scale = std::max(scale, std::abs(S.columns(r, c).v[0]));
        ASSERT_NEAR(dyn.S.columns(r, c), S.columns(r, c).a, 1e-14) << what;
      }
    EXPECT_LT(worst, 1e-12 * scale) << what << ": largest |dS/dt| " << scale;
  }
}

TEST(Rnea, MotionSubspaceRateIsTheJetPassesDerivative) {
  std::mt19937 rng(11);
  const Model& m = walker();
  expect_rate_is_the_jet_pass(m, rng, "walker");
  const int n = m.num_coordinates();
  const Eigen::VectorXd q = random_vector(n, rng, 0.5), qd = random_vector(n, rng, 2.0), qdd = random_vector(n, rng, 5.0);
  DynamicsWorkspace dyn(m);
  rnea_kinematics(m, q.data(), qd.data(), dyn);
  Eigen::VectorXd tau_parts(n);
  rnea_from_kinematics(m, qd.data(), qdd.data(), {}, dyn, tau_parts.data());
  EXPECT_LT((tau_parts - rnea_tau(m, q, qd, qdd)).cwiseAbs().maxCoeff(), 1e-12);
}

// The same on every model under ../shared: ball joints, spline-coupled knees, 2.x documents, couplers.
TEST(Rnea, MotionSubspaceRateOnEveryReferenceModel) {
  const std::string root = refdata::shared_path("opensim");
  REQUIRE_REFERENCE(root);
  std::mt19937 rng(12);
  int models = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
    if (e.path().extension() != ".osim") continue;
    const Model m = read_osim(e.path().string()).model;
    if (m.num_coordinates() == 0) continue;
    expect_rate_is_the_jet_pass(m, rng, e.path().string());
    ++models;
  }
  EXPECT_GE(models, 30);
}

TEST(Rnea, StaticPoseBalancesGravityExactly) {
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(5);
  const Eigen::VectorXd q = random_vector(n, rng, 0.5), zero = Eigen::VectorXd::Zero(n);
  const Eigen::VectorXd tau = rnea_tau(m, q, zero, zero);
  // The vertical pelvis force carries the whole weight.
  EXPECT_NEAR(tau[m.coordinate_index("pelvis_ty")], -m.total_mass_kg() * m.gravity_m_s2.y(), 1e-9);
  for (int c = 0; c < n; ++c) {
    Eigen::VectorXd a = q, b = q;
    a[c] += 1e-6;
    b[c] -= 1e-6;
    EXPECT_NEAR(tau[c], (potential_energy(m, a) - potential_energy(m, b)) / 2e-6, 1e-5) << m.coordinates[c].name;
  }
}

TEST(Rnea, ExternalForceEqualsJacobianTranspose) {
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(9);
  const Eigen::VectorXd q = random_vector(n, rng, 0.5), zero = Eigen::VectorXd::Zero(n);
  const int heel = m.marker_index("R.Heel");
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  forward_kinematics(m, q.data(), ws);
  motion_subspace(m, q.data(), ws, S);
  const Eigen::Vector3d p = marker_position(m, heel, ws), F(30, 700, -20), torque(1, 2, 3);
  std::vector<Vector6d> ext(m.bodies.size(), Vector6d::Zero());
  ext[m.markers[heel].body] = spatial_force(F, p, torque);
  const Eigen::VectorXd diff = rnea_tau(m, q, zero, zero) - rnea_tau(m, q, zero, zero, ext);
  const auto anc = ancestor_coordinates(m, m.markers[heel].body);
  for (int c = 0; c < n; ++c) {
    const bool moves = std::find(anc.begin(), anc.end(), c) != anc.end();
    const Eigen::Vector3d w = S.columns.col(c).head<3>(), dp = w.cross(p) + S.columns.col(c).tail<3>();
    EXPECT_NEAR(diff[c], moves ? F.dot(dp) + torque.dot(w) : 0.0, 1e-9) << m.coordinates[c].name;
  }
}

TEST(Lowpass, ButterworthGainAndZeroPhase) {
  const double dt = 0.01, fc = 6.0;
  const int n = 2000;
  auto sine = [&](double f) {
    Eigen::VectorXd x(n);
    for (int i = 0; i < n; ++i) x[i] = std::sin(2 * M_PI * f * i * dt);
    return x;
  };
  // Forward-backward: |H(fc)|^2 = 1/2 at the cutoff, ~1 well below, ~0 well above; no phase shift.
  const Eigen::VectorXd at = lowpass_butterworth3_zero_phase(sine(fc), dt, fc);
  const Eigen::VectorXd low = lowpass_butterworth3_zero_phase(sine(0.5), dt, fc);
  const Eigen::VectorXd high = lowpass_butterworth3_zero_phase(sine(30), dt, fc);
  const auto mid = Eigen::seqN(n / 4, n / 2);
  EXPECT_NEAR(at(mid).cwiseAbs().maxCoeff(), 0.5, 0.01);
  EXPECT_NEAR(low(mid).cwiseAbs().maxCoeff(), 1.0, 1e-3);
  EXPECT_LT(high(mid).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_LT((low - sine(0.5))(mid).cwiseAbs().maxCoeff(), 1e-3);  // zero phase
  const Eigen::VectorXd padded = pad_odd_reflection(Eigen::VectorXd::LinSpaced(10, 0, 9), 4);
  EXPECT_EQ(padded.size(), 18);
  EXPECT_DOUBLE_EQ(padded[0], -4);   // the reflection keeps the slope
  EXPECT_DOUBLE_EQ(padded[17], 13);
}

TEST(InverseDynamics, RecoversTorquesOfASyntheticMotion) {
  // Coordinates sampled from known smooth functions: ID's derivatives and forces must match RNEA on
  // the exact q, qd, qdd away from the ends.
  const Model& m = walker();
  const int n = m.num_coordinates();
  Storage coords;
  coords.in_degrees = false;
  coords.labels.push_back("time");
  for (const auto& c : m.coordinates) coords.labels.push_back(c.name);
  const int rows = 201;
  const double dt = 0.005;
  coords.data.resize(rows, n + 1);
  auto qf = [&](double t, int c, int d) {  // d-th derivative of 0.3 sin(w t + c)
    const double w = 2.0 + 0.1 * c;
    const double s = std::sin(w * t + c), co = std::cos(w * t + c);
    return d == 0 ? 0.3 * s : d == 1 ? 0.3 * w * co : -0.3 * w * w * s;
  };
  for (int r = 0; r < rows; ++r) {
    coords.data(r, 0) = r * dt;
    for (int c = 0; c < n; ++c) coords.data(r, c + 1) = qf(r * dt, c, 0);
  }
  InverseDynamicsOptions o;
  o.time_range_s = std::make_pair(0.2, 0.8);
  const InverseDynamicsResult r = inverse_dynamics(m, coords, nullptr, o);
  ASSERT_EQ(r.time_s.size(), 121u);
  double worst = 0;
  for (std::size_t i = 0; i < r.time_s.size(); ++i) {
    Eigen::VectorXd q(n), qd(n), qdd(n);
    for (int c = 0; c < n; ++c) q[c] = qf(r.time_s[i], c, 0), qd[c] = qf(r.time_s[i], c, 1), qdd[c] = qf(r.time_s[i], c, 2);
    worst = std::max(worst, (rnea_tau(m, q, qd, qdd).transpose() - r.generalized_forces.row(i)).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 0.05) << "N m or N";  // spline derivatives of 200 Hz samples
  const Storage table = inverse_dynamics_table(m, r);
  EXPECT_EQ(table.labels[m.coordinate_index("pelvis_tx") + 1], "pelvis_tx_force");
  EXPECT_EQ(table.labels[m.coordinate_index("knee_angle_r") + 1], "knee_angle_r_moment");
}

// Times rounded in the file (60 Hz to the millisecond, as subject01's TRC and IK hold them): the
// trajectories are resampled onto an even grid before differentiating, so their values at the sample
// times are the spline's, off the recorded ones; the recorded rows stay as the file has them, in
// internal units, for fits to the recorded poses.
TEST(InverseDynamics, KeepsTheRecordedRowsOfATableWithRoundedTimes) {
  const Model& m = walker();
  const int n = m.num_coordinates(), rows = 60;
  const int knee = m.coordinate_index("knee_angle_r"), tx = m.coordinate_index("pelvis_tx"), absent = m.coordinate_index("hip_flexion_l");
  auto time = [](int r) { return std::round(1000.0 * r / 60.0) / 1000.0; };
  auto value = [&](int r, int c) {  // degrees for angles
    return c == knee ? 40 * std::sin(6.0 * r / 60.0) : c == tx ? 1.2 * r / 60.0 + 0.01 * std::sin(9.0 * r / 60.0) : 0.1 * c;
  };
  // The table, without hip_flexion_l's column.
  Storage coords;
  coords.in_degrees = true;
  coords.labels.push_back("time");
  for (int c = 0; c < n; ++c)
    if (c != absent) coords.labels.push_back(m.coordinates[c].name);
  coords.data.resize(rows, n);
  for (int r = 0; r < rows; ++r) {
    coords.data(r, 0) = time(r);
    for (int c = 0, col = 1; c < n; ++c)
      if (c != absent) coords.data(r, col++) = value(r, c);
  }
  const CoordinateTrajectories k = coordinate_trajectories(m, coords, {});
  bool said_uneven = false;
  for (const auto& w : k.warnings) said_uneven = said_uneven || w.find("unevenly spaced") != std::string::npos;
  EXPECT_TRUE(said_uneven);
  ASSERT_EQ(k.recorded_time_s.size(), static_cast<std::size_t>(rows));
  ASSERT_EQ(k.q_recorded.rows(), rows);
  ASSERT_EQ(k.q_recorded.cols(), n);
  for (int r = 0; r < rows; ++r) {
    EXPECT_EQ(k.recorded_time_s[r], time(r));
    EXPECT_EQ(k.q_recorded(r, knee), value(r, knee) * (M_PI / 180.0));
    EXPECT_EQ(k.q_recorded(r, tx), value(r, tx));  // a translation: not converted
    EXPECT_EQ(k.q_recorded(r, absent), m.coordinates[absent].default_value);  // as the trajectories hold it
  }
  // The resampled values at the sample times are the spline's, off the recorded ones: a fit to them
  // would move.
  EXPECT_GT((k.q.col(knee) - k.q_recorded.col(knee)).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(ExternalLoads, UnknownBodyOrColumnNamesTheXmlLine) {
  const std::string dir = ::testing::TempDir();
  const std::string xml = dir + "/loads.xml";
  {
    std::FILE* f = std::fopen(xml.c_str(), "w");
    std::fputs("<OpenSimDocument Version=\"40000\"><ExternalLoads name=\"x\"><objects>\n"
               "<ExternalForce name=\"a\"><applied_to_body>foot_r</applied_to_body><force_identifier>f_v</force_identifier>"
               "<point_identifier>f_p</point_identifier></ExternalForce>\n"
               "<ExternalForce name=\"b\"><applied_to_body>wing</applied_to_body><force_identifier>f_v</force_identifier></ExternalForce>\n"
               "</objects><datafile>grf.mot</datafile></ExternalLoads></OpenSimDocument>\n", f);
    std::fclose(f);
  }
  const ExternalLoadsSpec spec = read_external_loads(xml);
  ASSERT_EQ(spec.forces.size(), 2u);
  Storage data;
  data.labels = {"time", "f_vx", "f_vy", "f_vz", "f_px", "f_py", "f_pz"};
  data.data = Eigen::MatrixXd::Zero(3, 7);
  try {
    AppliedLoads(walker(), spec, data);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.field(), "applied_to_body");
  }
  ExternalLoadsSpec one = spec;
  one.forces.pop_back();
  data.labels[5] = "f_qy";
  EXPECT_THROW(AppliedLoads(walker(), one, data), InputError);
}

// OpenSim matches an identifier to the first three columns that begin with it: gait10dof18musc's
// GRF file names its torques ground_torque_x/_y/_z, which "ground_torque" and "ground_torque_" both
// name, as OpenSim accepts either.
TEST(ExternalLoads, IdentifiersMatchColumnsAsOpenSimMatchesThem) {
  const std::string grf = refdata::shared_path("opensim/gait10dof18musc/ExperimentalData/subject01_walk_grf.mot");
  REQUIRE_REFERENCE(grf);
  const Storage data = read_storage(grf);
  auto torques = [&](const std::string& torque_identifier) {
    ExternalLoadsSpec spec;
    spec.file = "loads.xml";
    ExternalForceSpec f;
    f.name = "right";
    f.applied_to_body = walker().bodies[1].name;
    f.force_identifier = "ground_force_v";
    f.point_identifier = "ground_force_p";
    f.torque_identifier = torque_identifier;
    spec.forces.push_back(f);
    const AppliedLoads loads(walker(), spec, data);
    KinematicsWorkspace<double> ws(walker());
    const Eigen::VectorXd q = walker().default_coordinates();
    forward_kinematics(walker(), q.data(), ws);
    std::vector<AppliedLoads::Sample> out;
    loads.forces_at(0.8, ws, out);
    return out.at(0);
  };
  const auto a = torques("ground_torque_"), b = torques("ground_torque");
  EXPECT_EQ(a.torque_Nm, b.torque_Nm);
  EXPECT_GT(a.torque_Nm.norm(), 0.0);
  const int row = std::lower_bound(data.time().data(), data.time().data() + data.num_rows(), 0.8) - data.time().data();
  ASSERT_NEAR(data.time()[row], 0.8, 1e-9);
  EXPECT_DOUBLE_EQ(a.torque_Nm.y(), data.data(row, refdata::required_column(data, "ground_torque_y")));
  EXPECT_DOUBLE_EQ(a.force_N.y(), data.data(row, refdata::required_column(data, "ground_force_vy")));
  EXPECT_THROW(torques("ground_torques"), InputError);
}

// The mass matrix two ways: the composite-rigid-body algorithm, and columns of RNEA with unit
// accelerations at zero speed (M e_i = ID(q, 0, e_i) - ID(q, 0, 0)).
TEST(Crba, MatchesUnitAccelerationsThroughRnea) {
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(13);
  ForwardDynamicsWorkspace ws(m);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = random_vector(n, rng, 0.6), zero = Eigen::VectorXd::Zero(n);
    forward_kinematics(m, q.data(), ws.kinematics);
    motion_subspace(m, q.data(), ws.kinematics, ws.S);
    crba(m, ws.kinematics, ws.S, ws.M, ws.composite);
    const Eigen::VectorXd g = rnea_tau(m, q, zero, zero);
    for (int i = 0; i < n; ++i) {
      Eigen::VectorXd e = zero;
      e[i] = 1;
      EXPECT_LT((rnea_tau(m, q, zero, e) - g - ws.M.col(i)).cwiseAbs().maxCoeff(), 1e-10) << m.coordinates[i].name;
    }
    EXPECT_LT((ws.M - ws.M.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(ws.M).eigenvalues().minCoeff(), 0.0);
    // 1/2 qd' M qd is the kinetic energy computed body by body.
    const Eigen::VectorXd qd = random_vector(n, rng, 2.0);
    EXPECT_NEAR(0.5 * qd.dot(ws.M * qd), kinetic_energy(m, q, qd), 1e-10 * (1 + kinetic_energy(m, q, qd)));
  }
}

// The tree's LTL factor solves as a dense Cholesky does on every reference model's mass matrix (and
// on M plus a muscle's and a foot contact's coupling, which stay on one branch); a matrix coupling
// two branches, a non-definite one and an order with a parent after its child are refused sparsely.
// "walker" (the synthetic model) and every .osim under ../shared, or the walker alone without them.
static std::vector<std::filesystem::path> walker_and_reference_models() {
  std::vector<std::filesystem::path> files{"walker"};
  const std::string root = refdata::shared_path("opensim");
  if (std::filesystem::exists(root)) {
    for (const auto& e : std::filesystem::recursive_directory_iterator(root))
      if (e.path().extension() == ".osim") files.push_back(e.path());
  } else {
    std::cout << "reference data absent (" << root << "): the walker alone" << std::endl;
  }
  return files;
}

// The articulated-body algorithm gives CRBA's accelerations (M^-1 (tau - bias), external forces and
// all) on every model under ../shared, and refuses where M is singular (BothLegs' massless chains).
TEST(ArticulatedBody, AccelerationsAreCrbasOnEveryReferenceModel) {
  const std::vector<std::filesystem::path> files = walker_and_reference_models();
  std::mt19937 rng(7);
  int models = 0, refused = 0;
  for (const auto& e : files) {
    const Model m = e == "walker" ? walker() : read_osim(e.string()).model;
    const int n = m.num_coordinates();
    if (n == 0) continue;
    ++models;
    for (int trial = 0; trial < 3; ++trial) {
      Eigen::VectorXd q(n);
      for (int c = 0; c < n; ++c) q[c] = m.coordinates[c].default_value + std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
      const Eigen::VectorXd qd = random_vector(n, rng, 2.0), tau = random_vector(n, rng, 50.0);
      std::vector<Vector6d> external(m.bodies.size(), Vector6d::Zero());
      for (std::size_t b = 1; b < m.bodies.size(); b += 2) external[b] = random_vector(6, rng, 100.0);
      ForwardDynamicsWorkspace fd(m);
      Eigen::VectorXd qdd_crba(n), qdd(n);
      forward_dynamics(m, q.data(), qd.data(), tau.data(), external, fd, qdd_crba.data());
      ArticulatedBodyWorkspace aw(m);
      const bool solved = articulated_body_accelerations(m, qd.data(), tau.data(), external, fd.dynamics, aw, qdd.data());
      if (!fd.llt.success() || !qdd_crba.allFinite()) {
        EXPECT_FALSE(solved) << e;
        ++refused;
        break;
      }
      ASSERT_TRUE(solved) << e;
      EXPECT_LT((qdd - qdd_crba).norm(), 1e-8 * (1 + qdd_crba.norm())) << e;
    }
  }
  EXPECT_GE(models, files.size() > 1 ? 30 : 1);
  if (files.size() > 1) {
    EXPECT_GE(refused, 1) << "BothLegs' massless chains";
  }
}

namespace {
// The model's mass matrix at its default pose moved by up to 0.3 (rad or m) per coordinate.
Eigen::MatrixXd mass_matrix_near_default(const Model& m, std::mt19937& rng) {
  ForwardDynamicsWorkspace ws(m);
  Eigen::VectorXd q(m.num_coordinates());
  for (int c = 0; c < m.num_coordinates(); ++c)
    q[c] = m.coordinates[c].default_value + std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
  forward_kinematics(m, q.data(), ws.kinematics);
  motion_subspace(m, q.data(), ws.kinematics, ws.S);
  crba(m, ws.kinematics, ws.S, ws.M, ws.composite);
  return ws.M;
}
}  // namespace

TEST(TreeCholesky, SolvesMassMatricesAsDenseCholeskyOnEveryReferenceModel) {
  const std::vector<std::filesystem::path> files = walker_and_reference_models();
  std::mt19937 rng(5);
  int models = 0;
  for (const auto& e : files) {
    const Model m = e == "walker" ? walker() : read_osim(e.string()).model;
    const int n = m.num_coordinates();
    if (n < 2) continue;
    ++models;
    const Eigen::MatrixXd M = mass_matrix_near_default(m, rng);
    const std::vector<int> parent = coordinate_parents(m);
    if (M.llt().info() != Eigen::Success) {  // massless chains (BothLegs): refused alike
      TreeCholesky tree(parent);
      tree.compute(M);
      EXPECT_FALSE(tree.success()) << e;
      continue;
    }
    Eigen::MatrixXd A = M;
    // A chain's coupling: the deepest coordinate with its ancestors (as a muscle or a contact adds).
    int deep = n - 1;
    for (int j = deep; j >= 0; j = parent[j])
      for (int i = deep; i >= 0; i = parent[i]) A(i, j) += 0.5;
    for (const Eigen::MatrixXd* matrix : {&M, &std::as_const(A)}) {
      TreeCholesky tree(parent);
      tree.compute(*matrix);
      ASSERT_TRUE(tree.success()) << e;
      EXPECT_TRUE(tree.sparse()) << e;
      const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 3);
      const Eigen::MatrixXd x = tree.solve(B), x_dense = matrix->llt().solve(B);
      EXPECT_LT((x - x_dense).norm(), 1e-9 * x_dense.norm()) << e;
      Eigen::VectorXd b = B.col(0);
      tree.solve_in_place(b);
      EXPECT_LT((b - x_dense.col(0)).norm(), 1e-9 * x_dense.norm()) << e;
    }
    // Two coordinates on different branches coupled: dense, and still the solution.
    int other = -1;
    for (int i = 0; i < n && other < 0; ++i) {
      bool related = false;
      for (int j = deep; j >= 0; j = parent[j]) related = related || j == i;
      for (int j = i; j >= 0; j = parent[j]) related = related || j == deep;
      if (!related) other = i;
    }
    if (other >= 0) {
      Eigen::VectorXd v = Eigen::VectorXd::Zero(n);  // a positive coupling of the two: A stays definite
      v[other] = std::sqrt(A(other, other));
      v[deep] = std::sqrt(A(deep, deep));
      A += 0.1 * v * v.transpose();
      TreeCholesky tree(parent);
      tree.compute(A);
      EXPECT_TRUE(tree.success());
      EXPECT_FALSE(tree.sparse()) << e;
      const Eigen::VectorXd b = Eigen::VectorXd::Random(n);
      EXPECT_LT((tree.solve(b) - A.llt().solve(b)).norm(), 1e-9 * A.llt().solve(b).norm()) << e;
    }
  }
  EXPECT_GE(models, 1);
  // Not positive definite; a parent after its child.
  TreeCholesky chain({-1, 0});
  chain.compute((Eigen::Matrix2d() << 1, 2, 2, 1).finished());
  EXPECT_FALSE(chain.success());
  TreeCholesky reversed({1, -1});
  const Eigen::Matrix2d spd = (Eigen::Matrix2d() << 2, 1, 1, 2).finished();
  reversed.compute(spd);
  EXPECT_TRUE(reversed.success());
  EXPECT_FALSE(reversed.sparse());
  EXPECT_LT((reversed.solve(Eigen::Vector2d(1, 0)) - spd.llt().solve(Eigen::Vector2d(1, 0))).norm(), 1e-12);
}

TEST(TreeLU, SolvesUnsymmetricBranchCouplingsAsDenseLUOnEveryReferenceModel) {
  const std::vector<std::filesystem::path> files = walker_and_reference_models();
  std::mt19937 rng(6);
  int models = 0;
  for (const auto& e : files) {
    const Model m = e == "walker" ? walker() : read_osim(e.string()).model;
    const int n = m.num_coordinates();
    if (n < 2) continue;
    const Eigen::MatrixXd M = mass_matrix_near_default(m, rng);
    if (M.llt().info() != Eigen::Success) continue;  // massless chains (BothLegs)
    ++models;
    const std::vector<int> parent = coordinate_parents(m);
    // An unsymmetric coupling along the deepest chain (a foot's contact damping: friction follows the
    // normal force), skew and symmetric parts alike, kept small beside M so the symmetric part stays definite.
    const int deep = n - 1;
    std::vector<int> chain;
    for (int j = deep; j >= 0; j = parent[j]) chain.push_back(j);
    Eigen::MatrixXd A = M;
    const double scale = 0.2 * M.diagonal().minCoeff();
    for (int i : chain)
      for (int j : chain) A(i, j) += scale * std::uniform_real_distribution<double>(-1, 1)(rng);
    ASSERT_GT((A - A.transpose()).norm(), 0.0);
    TreeLU tree(parent);
    tree.compute(A);
    EXPECT_TRUE(tree.sparse()) << e;
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, 3);
    const Eigen::MatrixXd x = tree.solve(B), x_dense = A.partialPivLu().solve(B);
    EXPECT_LT((x - x_dense).norm(), 1e-9 * x_dense.norm()) << e;
    EXPECT_LT((A * x - B).norm(), 1e-9 * B.norm()) << e;
    Eigen::VectorXd b = B.col(0);
    tree.solve_in_place(b);
    EXPECT_LT((b - x_dense.col(0)).norm(), 1e-9 * x_dense.norm()) << e;
    // One entry on another branch (the last coordinate has no descendants), in the upper triangle
    // only: dense, and still the solution.
    int other = -1;
    for (int i = 0; i < n && other < 0; ++i)
      if (std::find(chain.begin(), chain.end(), i) == chain.end()) other = i;
    if (other >= 0) {
      Eigen::MatrixXd C = A;
      C(std::min(other, deep), std::max(other, deep)) += scale;
      tree.compute(C);
      EXPECT_FALSE(tree.sparse()) << e;
      EXPECT_LT((C * tree.solve(B) - B).norm(), 1e-9 * B.norm()) << e;
    }
  }
  EXPECT_GE(models, 1);
  // A pivot that is not positive (the symmetric part indefinite) and a parent after its child: dense.
  const Eigen::Matrix2d indefinite = (Eigen::Matrix2d() << 1, 2, 3, -1).finished();
  TreeLU chain({-1, 0});
  chain.compute(indefinite);
  EXPECT_FALSE(chain.sparse());
  EXPECT_LT((indefinite * chain.solve(Eigen::Vector2d(1, 2)) - Eigen::Vector2d(1, 2)).norm(), 1e-12);
  const Eigen::Matrix2d unsymmetric = (Eigen::Matrix2d() << 2, 1, -1, 2).finished();
  chain.compute(unsymmetric);
  EXPECT_TRUE(chain.sparse());
  EXPECT_LT((chain.solve(Eigen::Vector2d(1, 0)) - Eigen::Vector2d(0.4, 0.2)).norm(), 1e-12);  // by hand
  TreeLU reversed({1, -1});
  reversed.compute(unsymmetric);
  EXPECT_FALSE(reversed.sparse());
  EXPECT_LT((reversed.solve(Eigen::Vector2d(1, 0)) - Eigen::Vector2d(0.4, 0.2)).norm(), 1e-12);
}

TEST(ForwardDynamics, InverseOfInverseDynamics) {
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(17);
  ForwardDynamicsWorkspace ws(m);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = random_vector(n, rng, 0.6), qd = random_vector(n, rng, 2.0), tau = random_vector(n, rng, 50.0);
    std::vector<Vector6d> ext(m.bodies.size(), Vector6d::Zero());
    ext[m.body_index("foot_r")] = spatial_force(Eigen::Vector3d(10, 600, -5), Eigen::Vector3d(0.3, 0.0, 0.1));
    Eigen::VectorXd qdd(n);
    forward_dynamics(m, q.data(), qd.data(), tau.data(), ext, ws, qdd.data());
    const Eigen::VectorXd back = rnea_tau(m, q, qd, qdd, ext);
    EXPECT_LT((back - tau).cwiseAbs().maxCoeff(), 1e-9 * (1 + tau.cwiseAbs().maxCoeff())) << "trial " << trial;
  }
}

TEST(ForwardDynamics, PassiveModelConservesEnergy) {
  // The fixture model falling and tumbling freely under gravity, no joint torques: classical RK4 at
  // 0.1 ms for half a second keeps kinetic + potential energy constant.
  const Model& m = walker();
  const int n = m.num_coordinates();
  std::mt19937 rng(19);
  ForwardDynamicsWorkspace ws(m);
  Eigen::VectorXd q = random_vector(n, rng, 0.3), qd = random_vector(n, rng, 1.0);
  q[m.coordinate_index("lumbar_rotation")] = 0;  // locked coordinates are still integrated here; keep it tidy
  const Eigen::VectorXd tau = Eigen::VectorXd::Zero(n);
  const std::vector<Vector6d> none;
  auto accel = [&](const Eigen::VectorXd& qq, const Eigen::VectorXd& vv) {
    Eigen::VectorXd a(n);
    forward_dynamics(m, qq.data(), vv.data(), tau.data(), none, ws, a.data());
    return a;
  };
  const double e0 = mechanical_energy(m, q.data(), qd.data(), ws);
  const Eigen::MatrixXd M0 = ws.M;
  const Eigen::VectorXd qd0 = qd;
  const double h = 1e-4;
  for (int step = 0; step < 5000; ++step) {
    const Eigen::VectorXd a1 = accel(q, qd);
    const Eigen::VectorXd a2 = accel(q + 0.5 * h * qd, qd + 0.5 * h * a1);
    const Eigen::VectorXd a3 = accel(q + 0.5 * h * (qd + 0.5 * h * a1), qd + 0.5 * h * a2);
    const Eigen::VectorXd a4 = accel(q + h * (qd + 0.5 * h * a2), qd + h * a3);
    q += h * qd + h * h / 6.0 * (a1 + a2 + a3);
    qd += h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4);
  }
  const double e1 = mechanical_energy(m, q.data(), qd.data(), ws);
  EXPECT_LT(std::abs(e1 - e0), 1e-6 * std::abs(e0) + 1e-6) << "energy " << e0 << " -> " << e1 << " J";
  // And it really moved: half a second of free fall turns about m g^2 t^2 / 2 of potential energy
  // into kinetic energy.
  EXPECT_GT(0.5 * qd.dot(ws.M * qd) - 0.5 * qd0.dot(M0 * qd0), 0.5 * m.total_mass_kg() * 9.8 * 9.8 * 0.25 * 0.5);
}

// Foot-ground contact (Hunt-Crossley spheres): static balance, energy in a drop, friction, JSON.
TEST(Contact, HuntCrossleySphereBalancesDissipatesAndRubs) {
  ContactSet set;
  ContactSphere s;
  const double weight = 700.0;
  // Resting: the penetration where k d^1.5 = weight carries the weight.
  const double d = std::pow(weight / s.stiffness, 2.0 / 3.0);
  const Eigen::Vector3d f = sphere_contact_force(s, set, Eigen::Vector3d(0, s.radius_m - d, 0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(f.y(), weight, 1e-3 * weight);
  EXPECT_NEAR(f.x(), 0.0, 1e-6);
  // Away from the ground: (smoothly) nothing.
  EXPECT_LT(sphere_contact_force(s, set, Eigen::Vector3d(0, s.radius_m + 0.01, 0), Eigen::Vector3d(0, -1, 0)).norm(), 1e-6);
  // A 70 kg point dropped from 5 cm: without dissipation it bounces back to its height, with it lower.
  auto rebound = [&](double c) {
    ContactSphere b = s;
    b.dissipation = c;
    double y = s.radius_m + 0.05, v = 0, top = -1;
    bool touched = false;
    for (int i = 0; i < 400000; ++i) {  // 2 s at 5 us, semi-implicit Euler
      const double fy = sphere_contact_force(b, set, Eigen::Vector3d(0, y, 0), Eigen::Vector3d(0, v, 0)).y();
      v += (fy / 70.0 - 9.81) * 5e-6;
      y += v * 5e-6;
      if (y < s.radius_m) touched = true;
      if (touched && y > s.radius_m && v < 0 && top < 0) top = y - s.radius_m;  // first apex after the bounce
    }
    return top;
  };
  const double elastic = rebound(0.0), damped = rebound(0.5), foot = rebound(s.dissipation);
  EXPECT_NEAR(elastic, 0.05, 0.002);
  EXPECT_LT(damped, 0.8 * elastic);
  EXPECT_GT(damped, 0.0);
  EXPECT_LT(foot, 0.0);  // the default (2 s/m) does not bounce a foot at all
  // Sliding at 1 m/s along x under 700 N: friction opposes it, about mu_d + viscous times the load.
  const Eigen::Vector3d slide = sphere_contact_force(s, set, Eigen::Vector3d(0, s.radius_m - d, 0), Eigen::Vector3d(1, 0, 0));
  EXPECT_LT(slide.x(), 0.0);
  EXPECT_NEAR(-slide.x() / slide.y(), s.dynamic_friction + s.viscous_friction * 1.0, 0.05);
  EXPECT_NEAR(slide.z(), 0.0, 1e-9);
}

TEST(Contact, JsonSideFileAndDefaultFeet) {
  const Model m = read_osim(refdata::fixture("models/walker.osim")).model;
  const ContactSet def = default_foot_contacts(m);
  EXPECT_EQ(def.spheres.size(), 4u);
  // Five per foot: both heels' and the metatarsal heads' spheres either side of the foot's midline,
  // the right foot's mirrored on the left, every bottom level with the heel's in the default pose.
  const ContactSet five = default_foot_contacts(m, 5);
  ASSERT_EQ(five.spheres.size(), 10u);
  KinematicsWorkspace<double> kws(m);
  Eigen::VectorXd q(m.num_coordinates());
  for (int c = 0; c < m.num_coordinates(); ++c) q[c] = m.coordinates[static_cast<std::size_t>(c)].default_value;
  forward_kinematics(m, q.data(), kws);
  auto bottom_m = [&](const ContactSphere& s) { return sphere_centre_m(kws, s).y() - s.radius_m; };
  for (std::size_t i = 0; i < 5; ++i) {
    const ContactSphere &r = five.spheres[i], &l = five.spheres[5 + i];
    EXPECT_EQ(r.name.substr(0, r.name.size() - 2) + "_l", l.name);
    EXPECT_EQ(r.name.substr(r.name.size() - 2), "_r");
    EXPECT_NEAR(r.location_m.z(), -l.location_m.z(), 1e-12) << r.name;
    EXPECT_NEAR(bottom_m(r), bottom_m(five.spheres[0]), 1e-9) << r.name;
    EXPECT_NEAR(bottom_m(l), bottom_m(five.spheres[5]), 1e-9) << l.name;
  }
  EXPECT_LT(five.spheres[0].location_m.z() * five.spheres[1].location_m.z(), 0.0);  // medial and lateral heel
  EXPECT_LT(five.spheres[2].location_m.z() * five.spheres[3].location_m.z(), 0.0);  // first and fifth metatarsal heads
  EXPECT_THROW(default_foot_contacts(m, 3), std::invalid_argument);
  const ContactSet set = parse_contact_set_json(
      R"({"ground_height_m": 0.01, "defaults": {"stiffness": 2e6}, "spheres": [
           {"name": "heel", "body": "foot_r", "location_m": [0, -0.04, 0], "radius_m": 0.03},
           {"name": "toe", "body": "foot_r", "location_m": [0.16, -0.04, 0], "dissipation": 1.0}]})",
      "feet.json", m);
  ASSERT_EQ(set.spheres.size(), 2u);
  EXPECT_DOUBLE_EQ(set.ground_height_m, 0.01);
  EXPECT_DOUBLE_EQ(set.spheres[0].stiffness, 2e6);
  EXPECT_DOUBLE_EQ(set.spheres[1].dissipation, 1.0);
  EXPECT_EQ(set.spheres[0].body, m.body_index("foot_r"));
  auto field_of = [&](const std::string& text) {
    try {
      parse_contact_set_json(text, "feet.json", m);
    } catch (const InputError& e) {
      return e.field();
    }
    return std::string("no error");
  };
  EXPECT_EQ(field_of(R"({"spheres": [{"body": "hoof", "location_m": [0, 0, 0]}]})"), "spheres[0].body");
  EXPECT_EQ(field_of(R"({"spheres": [{"body": "foot_r", "location_m": [0, 0]}]})"), "spheres[0].location_m");
  EXPECT_EQ(field_of(R"({"spheres": [{"body": "foot_r", "location_m": [0, 0, 0], "radius_m": -1}]})"), "spheres[0].radius_m");
  EXPECT_EQ(field_of(R"({"spheres": []})"), "spheres");
}

// Spheres fitted to a trial: each touches the ground at its lowest, all sink by one depth, and the
// trial's poses then load them with body weight on average - checked here with the contact force
// itself, pose by pose. A sphere that never comes near the ground is left as it was.
TEST(Contact, FootSpheresFittedToATrialCarryBodyWeightOnAverage) {
  const Model& m = walker();
  // Standing and rocking: the body bobs 1 cm while the feet roll heel to toe in turn.
  const int n = 200;
  Eigen::MatrixXd q(n, m.num_coordinates());
  std::vector<double> t;
  for (int i = 0; i < n; ++i) {
    const double ph = 2 * M_PI * i / 100.0;
    Eigen::VectorXd qi = m.default_coordinates();
    qi[m.coordinate_index("pelvis_ty")] += 0.01 * std::sin(ph);
    qi[m.coordinate_index("ankle_angle_r")] += 0.15 * std::sin(ph);
    qi[m.coordinate_index("ankle_angle_l")] -= 0.15 * std::sin(ph);
    q.row(i) = qi.transpose();
    t.push_back(i * 0.01);
  }
  ContactSet set = default_foot_contacts(m);
  ContactSphere head = set.spheres.front();
  head.name = "head";
  head.body = m.body_index("torso");
  ASSERT_GT(head.body, 0);
  set.spheres.push_back(head);
  const ContactSet before = set;
  const FootSphereFit fit = fit_foot_spheres_to_trial(m, set, t, q);
  ASSERT_EQ(fit.radius_change_m.size(), set.spheres.size());
  EXPECT_GT(fit.depth_m, 0.001);
  EXPECT_LT(fit.depth_m, 0.02);
  EXPECT_EQ(fit.radius_change_m.back(), 0.0);
  EXPECT_EQ(set.spheres.back().radius_m, before.spheres.back().radius_m);
  ASSERT_EQ(fit.warnings.size(), 1u);
  EXPECT_NE(fit.warnings[0].find("head"), std::string::npos);

  KinematicsWorkspace<double> kws(m);
  std::vector<double> lowest(set.spheres.size(), 1e9);
  double total_N = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::VectorXd qi = q.row(i).transpose();
    forward_kinematics(m, qi.data(), kws);
    for (std::size_t s = 0; s < set.spheres.size(); ++s) {
      const auto& B = kws.body_in_ground[static_cast<std::size_t>(set.spheres[s].body)];
      const Eigen::Vector3d c = B.rotation * set.spheres[s].location_m + B.translation_m;
      lowest[s] = std::min(lowest[s], c.y() - set.spheres[s].radius_m - set.ground_height_m);
      total_N += sphere_contact_force(set.spheres[s], set, c, Eigen::Vector3d::Zero()).y();
    }
  }
  const double weight_N = m.total_mass_kg() * m.gravity_m_s2.norm();
  EXPECT_NEAR(total_N / n, weight_N, 0.01 * weight_N);
  for (std::size_t s = 0; s + 1 < set.spheres.size(); ++s) EXPECT_NEAR(lowest[s], -fit.depth_m, 1e-9) << set.spheres[s].name;
}

// Friction acts on the velocity of the sphere's point in contact, not of its centre: a foot rolling
// over its heel sphere without slipping feels no friction, however fast the centre moves, while the
// same foot sliding does.
TEST(Contact, ARollingFootDoesNotSlip) {
  const Model& m = walker();
  ContactSet feet = default_foot_contacts(m);
  MuscleDrivenSystem sys;
  sys.model = &m;
  sys.contacts = &feet;
  MuscleDrivenWorkspace ws(sys);
  const int nq = m.num_coordinates();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), xdot(sys.state_size()), none(0);
  x.head(nq) = m.default_coordinates();
  const Eigen::VectorXd e = Eigen::VectorXd::Zero(sys.num_muscles());
  // The ground 5 mm into the right heel sphere.
  const int heel = 0;
  ASSERT_EQ(feet.spheres[heel].name, "heel_r");
  muscle_driven_derivatives(sys, 0.0, x, e, none, ws, xdot);
  feet.ground_height_m = ws.contact_point_m[heel].y() + 0.005;
  // Rolling: the ankle turns at 3 rad/s and the pelvis moves so that the contact point stands still.
  muscle_driven_derivatives(sys, 0.0, x, e, none, ws, xdot);
  const Eigen::Vector3d p = ws.contact_point_m[heel];
  const std::vector<int> chain = ancestor_coordinates(m, feet.spheres[heel].body);
  const int ankle = m.coordinate_index("ankle_angle_r");
  std::vector<int> pelvis;
  for (const char* c : {"pelvis_tilt", "pelvis_list", "pelvis_rotation", "pelvis_tx", "pelvis_ty", "pelvis_tz"}) pelvis.push_back(m.coordinate_index(c));
  Eigen::Matrix<double, 3, 6> Jp;
  for (int j = 0; j < 6; ++j) Jp.col(j) = point_velocity_column(ws.fd.S, pelvis[static_cast<std::size_t>(j)], p);
  const Eigen::Vector3d ankle_velocity = point_velocity_column(ws.fd.S, ankle, p) * 3.0;
  const Eigen::VectorXd u_pelvis = Jp.completeOrthogonalDecomposition().solve(-ankle_velocity);
  x.segment(nq, nq).setZero();
  x[nq + ankle] = 3.0;
  for (int j = 0; j < 6; ++j) x[nq + pelvis[static_cast<std::size_t>(j)]] = u_pelvis[j];
  ASSERT_LT(point_velocity_in_ground(ws.fd.S, chain, p, x.data() + nq).norm(), 1e-9);
  const Eigen::Vector3d centre = p + feet.spheres[heel].radius_m * Eigen::Vector3d::UnitY();
  EXPECT_GT(point_velocity_in_ground(ws.fd.S, chain, centre, x.data() + nq).norm(), 0.08);  // the centre moves
  muscle_driven_derivatives(sys, 0.0, x, e, none, ws, xdot);
  const Eigen::Vector3d rolling = ws.contact_force_N[heel];
  ASSERT_GT(rolling.y(), 100.0);
  EXPECT_LT(std::hypot(rolling.x(), rolling.z()), 1e-3 * rolling.y());
  // Sliding: the whole body moving forwards at 0.1 m/s.
  x.segment(nq, nq).setZero();
  x[nq + m.coordinate_index("pelvis_tx")] = 0.1;
  muscle_driven_derivatives(sys, 0.0, x, e, none, ws, xdot);
  const Eigen::Vector3d sliding = ws.contact_force_N[heel];
  EXPECT_LT(sliding.x(), -0.5 * sliding.y());
}

// A coupled coordinate under forward dynamics (leg6dof9musc's patella, on a curved spline as in the IK
// test): falling and swinging under gravity alone, the model keeps its energy and, integrated without
// any projection, the coupled coordinate stays on its function to the integrator's error (the Forward
// tool also projects at every output). Leaving out the coupler's f'' qd^2 acceleration term breaks the
// energy balance (measured 2e-3 J).
TEST(CoordinateCouplers, ForwardDynamicsConservesEnergyOnTheConstraint) {
  const std::string path = refdata::shared_path("opensim/opensim-core-tests/CMC/leg6dof9musc.osim");
  REQUIRE_REFERENCE(path);
  Model m = read_osim(path).model;
  ASSERT_EQ(m.couplers.size(), 1u);
  CoordinateCoupler& c = m.couplers[0];
  c.function = Function::simm_spline({-2.1, -1.0, 0.0, 0.2}, {-1.4, -0.8, 0.05, 0.1});
  m.muscles.clear();
  MuscleDrivenSystem sys;
  sys.model = &m;
  MuscleDrivenWorkspace ws(sys);
  const int nq = m.num_coordinates();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), xdot(x.size()), none;
  x[m.coordinate_index("knee_angle_r")] = -0.8;
  x[m.coordinate_index("hip_flexion_r")] = 0.4;
  x[nq + m.coordinate_index("knee_angle_r")] = 3.0;  // rad/s
  x[nq + m.coordinate_index("hip_flexion_r")] = -2.0;
  apply_coordinate_couplers(m, x.data());
  auto energy = [&](const Eigen::VectorXd& s) {
    Eigen::VectorXd d(s.size());
    muscle_driven_derivatives(sys, 0.0, s, none, none, ws, d);
    const Eigen::VectorXd u = ws.x_coupled.segment(nq, nq);
    double e = 0.5 * u.dot(ws.fd.M * u);
    for (std::size_t b = 1; b < m.bodies.size(); ++b) {
      const auto& X = ws.fd.kinematics.body_in_ground[b];
      e -= m.bodies[b].mass_kg * m.gravity_m_s2.dot(X.rotation * m.bodies[b].com_m + X.translation_m);
    }
    return e;
  };
  const double e0 = energy(x);
  const double h = 1e-4;
  double worst_coupling = 0, worst_energy = 0;
  Eigen::VectorXd k1(x.size()), k2(x.size()), k3(x.size()), k4(x.size());
  for (int step = 0; step < 3000; ++step) {  // 0.3 s, RK4
    muscle_driven_derivatives(sys, 0, x, none, none, ws, k1);
    muscle_driven_derivatives(sys, 0, x + 0.5 * h * k1, none, none, ws, k2);
    muscle_driven_derivatives(sys, 0, x + 0.5 * h * k2, none, none, ws, k3);
    muscle_driven_derivatives(sys, 0, x + h * k3, none, none, ws, k4);
    x += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    worst_coupling = std::max(worst_coupling, std::abs(x[c.dependent] - c.scale * c.function.value(x[c.independent])));
    worst_energy = std::max(worst_energy, std::abs(energy(x) - e0));
  }
  std::printf("coupled forward dynamics over 0.3 s: coupling %.1e rad, energy drift %.1e J of %.1f J kinetic+potential\n",
              worst_coupling, worst_energy, e0);
  EXPECT_LT(worst_coupling, 1e-8);  // measured 2.5e-9 rad
  EXPECT_LT(worst_energy, 1e-5);    // measured 5e-7 J
}

// An integrator's stages skip the moment-arm matrix (MuscleGeometry::kLengthsAndSpeeds): the muscles'
// tensions go to the skeleton as body forces along their paths. The derivative must be the one
// R^T F gives, on every reference model with muscles: wrapping surfaces, moving and conditional
// points, couplers, rigid and compliant tendons.
TEST(MuscleDrivenDynamics, PathTensionsAsBodyForcesEqualMomentArmsOnEveryReferenceModel) {
  const std::string root = refdata::shared_path("opensim");
  REQUIRE_REFERENCE(root);
  std::mt19937 rng(21);
  std::normal_distribution<double> noise(0.0, 1.0);
  int models = 0, with_wraps = 0, with_moving_points = 0;
  double worst = 0;
  std::vector<std::filesystem::path> files{"walker"};
  for (const auto& e : std::filesystem::recursive_directory_iterator(root))
    if (e.path().extension() == ".osim") files.push_back(e.path());
  for (const auto& e : files) {
    const Model m = e == "walker" ? walker() : read_osim(e.string()).model;
    if (m.muscles.empty()) continue;
    bool moving = false;
    for (const auto& mu : m.muscles)
      for (const auto& p : mu.path) moving = moving || p.kind == PathPoint::Kind::kMoving;
    for (const bool compliant : {false, true}) {
      MuscleDrivenSystem sys;
      sys.model = &m;
      sys.compliant_tendons = compliant;
      MuscleDrivenWorkspace ws(sys);
      const int nq = m.num_coordinates(), nm = sys.num_muscles();
      Eigen::VectorXd x(sys.state_size());
      for (int c = 0; c < nq; ++c) {
        x[c] = m.coordinates[c].default_value + 0.1 * noise(rng);
        x[nq + c] = noise(rng);
      }
      for (int k = 0; k < nm; ++k) {
        x[sys.activation_index(k)] = 0.3;
        if (compliant) x[sys.fiber_length_index(k)] = m.muscles[k].optimal_fiber_length_m;
      }
      const Eigen::VectorXd excitation = Eigen::VectorXd::Constant(nm, 0.5), none;
      Eigen::VectorXd with_arms(x.size()), with_forces(x.size());
      muscle_driven_derivatives(sys, 0.0, x, excitation, none, ws, with_arms);
      const Eigen::VectorXd tau_arms = ws.tau;
      muscle_driven_derivatives(sys, 0.0, x, excitation, none, ws, with_forces, MuscleGeometry::kLengthsAndSpeeds);
      if (!with_arms.allFinite()) continue;
      const double scale = 1.0 + tau_arms.cwiseAbs().maxCoeff();
      const double d = (ws.tau - tau_arms).cwiseAbs().maxCoeff() / scale;
      worst = std::max(worst, d);
      EXPECT_LT(d, 1e-12) << e << (compliant ? " compliant" : " rigid");
      EXPECT_LT((with_forces - with_arms).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + with_arms.cwiseAbs().maxCoeff())) << e;
      if (!compliant) {
        ++models;
        with_wraps += !m.wrap_objects.empty();
        with_moving_points += moving;
      }
    }
  }
  std::printf("[info] %d models with muscles (%d with wrapping, %d with moving points): worst |tau difference| / (1 + |tau|) %.1e\n",
              models, with_wraps, with_moving_points, worst);
  EXPECT_GE(models, 10);
  EXPECT_GT(with_wraps, 0);
  EXPECT_GT(with_moving_points, 0);
}
