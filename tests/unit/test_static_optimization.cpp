#include <gtest/gtest.h>

#include <cstdio>

#include <limits>
#include <random>

#include "cpgait/activation/static_optimization.h"
#include "cpgait/capture/actuator_set.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/optim/dual_newton.h"
#include "test_support.h"

using namespace cpgait;

namespace {

using refdata::walker;

// KKT conditions of min sum |x|^p, Ax = b, lo <= x <= hi, given the multipliers.
void expect_kkt(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                double p, const Eigen::VectorXd& lambda, const Eigen::VectorXd& x) {
  EXPECT_LT((A * x - b).cwiseAbs().maxCoeff(), 1e-8);
  const Eigen::VectorXd s = A.transpose() * lambda;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    ASSERT_GE(x[i], lo[i] - 1e-12);
    ASSERT_LE(x[i], hi[i] + 1e-12);
    const double grad = p * std::pow(std::abs(x[i]), p - 1) * (x[i] < 0 ? -1 : 1);
    if (x[i] > lo[i] + 1e-9 && x[i] < hi[i] - 1e-9) EXPECT_NEAR(grad, s[i], 1e-6 * (1 + std::abs(s[i])));
    // dL/dx = grad - s: non-negative at a lower bound (raising x would not help), non-positive at an upper.
    else if (x[i] <= lo[i] + 1e-9) EXPECT_GE(grad - s[i], -1e-6);
    else EXPECT_LE(grad - s[i], 1e-6);
  }
}

std::vector<Vector6d> no_loads;

}  // namespace

TEST(DualNewton, SatisfiesKktOnRandomProblems) {
  // Own generator: Eigen's Random() draws from std::rand, whose state depends on what ran before.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random = [&](int rows, int cols) { return Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return u(rng); }).eval(); };
  for (double p : {2.0, 3.0, 4.0}) {
    for (int trial = 0; trial < 40; ++trial) {
      const int m = 6, n = 30;
      const Eigen::MatrixXd A = random(m, n);
      const Eigen::VectorXd x_feasible = random(n, 1).cwiseAbs() * 0.5;
      const Eigen::VectorXd b = A * x_feasible;
      Eigen::VectorXd lo = Eigen::VectorXd::Zero(n), hi = Eigen::VectorXd::Ones(n);
      lo.tail(3).setConstant(-1e3);  // a few free "reserves"
      hi.tail(3).setConstant(1e3);
      Eigen::VectorXd lambda, x;
      DualNewtonOptions o;
      o.exponent = p;
      o.tolerance = StaticOptimizationOptions().equality_tolerance;  // what static optimization asks
      const DualNewtonSummary s = minimize_power_sum(A, b, lo, hi, o, lambda, x);
      ASSERT_TRUE(s.converged) << "p=" << p << " trial " << trial << ": residual " << s.equality_residual << " after "
                               << s.iterations << " iterations";
      SCOPED_TRACE(::testing::Message() << "p=" << p << " trial " << trial << " outer " << s.outer_iterations << " inner " << s.iterations);
      expect_kkt(A, b, lo, hi, p, lambda, x);
      // No feasible point nearby is better: perturb within the null space of A, stay in bounds.
      const Eigen::MatrixXd N = A.fullPivLu().kernel();
      const double f = x.array().abs().pow(p).sum();
      for (int k = 0; k < 20; ++k) {
        const Eigen::VectorXd y = x + 1e-3 * N * random(static_cast<int>(N.cols()), 1);
        if ((y.array() < lo.array()).any() || (y.array() > hi.array()).any()) continue;
        EXPECT_GE(y.array().abs().pow(p).sum(), f - 1e-12);
      }
    }
  }
}

namespace {
// Static optimization's and CMC's shape: 23 coordinates, 92 muscle columns each crossing 1-4 of
// them (bounds 0 and 1), and a weak reserve on each coordinate (bounds -+1000).
constexpr int kCoordinates = 23, kMuscles = 92;
struct MuscleShapedProgram {
  Eigen::MatrixXd A;
  Eigen::VectorXd lo, hi;
};
MuscleShapedProgram muscle_shaped_program(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> row(0, kCoordinates - 1), crossed(1, 4);
  const int n = kMuscles + kCoordinates;
  MuscleShapedProgram p{Eigen::MatrixXd::Zero(kCoordinates, n), Eigen::VectorXd::Zero(n), Eigen::VectorXd::Ones(n)};
  for (int k = 0; k < kMuscles; ++k)
    for (int c = crossed(rng); c > 0; --c) p.A(row(rng), k) = u(rng);
  p.A.rightCols(kCoordinates).diagonal().setConstant(0.01);
  p.lo.tail(kCoordinates).setConstant(-1e3);
  p.hi.tail(kCoordinates).setConstant(1e3);
  return p;
}
}  // namespace

// There A D A^T is summed over each column's nonzero rows (its pairs are a sixth of the dense
// product's): the solution must meet the KKT conditions in as few Newton steps.
TEST(DualNewton, SparseColumnsSolveInAFewSteps) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    const auto [A, lo, hi] = muscle_shaped_program(rng);
    const Eigen::VectorXd x_feasible = Eigen::VectorXd::NullaryExpr(A.cols(), [&] { return 0.5 * std::abs(u(rng)); });
    const Eigen::VectorXd b = A.leftCols(kMuscles) * x_feasible.head(kMuscles);
    Eigen::VectorXd lambda, x;
    DualNewtonOptions o;
    o.tolerance = 1e-9;  // CMC's
    const DualNewtonSummary s = minimize_power_sum(A, b, lo, hi, o, lambda, x);
    SCOPED_TRACE(::testing::Message() << "trial " << trial << ": " << s.iterations << " iterations");
    ASSERT_TRUE(s.converged) << "residual " << s.equality_residual;
    EXPECT_LE(s.iterations, 10);
    expect_kkt(A, b, lo, hi, 2.0, lambda, x);
  }
}

// CMC's sequence: each window's program warm-started from the last one's multipliers while the
// forces asked for drift and muscles reach their bounds. A Newton step then crosses breakpoints of
// the dual; with exact_line_search it goes to the dual's maximiser along it, which the line search
// accepts as it stands. Measured: 367 steps and as many dual evaluations; halving from the full
// step, 387 steps and 454 evaluations (on subject01's CMC: 2,927 steps, ~6 evaluations each).
TEST(DualNewton, WarmStartedSequenceTakesFewSteps) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto [A, lo, hi] = muscle_shaped_program(rng);
  const Eigen::VectorXd phase = Eigen::VectorXd::NullaryExpr(kMuscles, [&] { return 3.0 * u(rng); });
  int steps[2] = {0, 0}, evaluations[2] = {0, 0};
  const int programs = 100;
  for (bool exact : {false, true}) {
    Eigen::VectorXd lambda, x;
    DualNewtonOptions o;
    o.tolerance = 1e-9;
    o.exact_line_search = exact;
    for (int w = 0; w < programs; ++w) {
      // Activations that swing over the bounds as a gait's do, the forces asked for following them.
      const Eigen::VectorXd target = (1.2 * (phase.array() + 0.4 * w).sin() + 0.2).cwiseMax(0.0).cwiseMin(1.0).matrix();
      const Eigen::VectorXd b = A.leftCols(kMuscles) * target;
      const DualNewtonSummary s = minimize_power_sum(A, b, lo, hi, o, lambda, x);
      ASSERT_TRUE(s.converged) << "exact " << exact << ", program " << w << ": residual " << s.equality_residual;
      expect_kkt(A, b, lo, hi, 2.0, lambda, x);
      steps[exact] += s.iterations;
      evaluations[exact] += s.line_search_evaluations;
    }
    std::printf("[ info ] %d warm-started programs, %s: %d Newton steps, %d dual evaluations in their line searches\n", programs,
                exact ? "exact line search" : "halving", steps[exact], evaluations[exact]);
  }
  EXPECT_LE(evaluations[1], steps[1] + steps[1] / 20);
  EXPECT_LT(evaluations[1], evaluations[0]);
  EXPECT_LE(steps[1], 420) << "regression bound";
}

// A warm start that cannot converge (here multipliers that are not even finite; in CMC, multipliers
// whose rounding floor lies above the tolerance) is retried from the cold start, which converges.
TEST(DualNewton, FailedWarmStartRetriesCold) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random = [&](int rows, int cols) { return Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return u(rng); }).eval(); };
  const int m = 6, n = 30;
  const Eigen::MatrixXd A = random(m, n);
  const Eigen::VectorXd b = A * (random(n, 1).cwiseAbs() * 0.5);
  const Eigen::VectorXd lo = Eigen::VectorXd::Zero(n), hi = Eigen::VectorXd::Ones(n);
  Eigen::VectorXd lambda = Eigen::VectorXd::Constant(m, std::numeric_limits<double>::quiet_NaN()), x;
  DualNewtonOptions o;
  const DualNewtonSummary s = minimize_power_sum(A, b, lo, hi, o, lambda, x);
  ASSERT_TRUE(s.converged) << "residual " << s.equality_residual;
  EXPECT_GT(s.iterations, o.max_iterations);  // the warm start's iterations are counted too
  expect_kkt(A, b, lo, hi, 2.0, lambda, x);
}

namespace {
Model without_muscles(const Model& m) {
  Model bare = m;
  bare.muscles.clear();
  return bare;
}
// One coordinate actuator per coordinate, named <coordinate>_reserve.
std::vector<ActuatorSpec> reserves(const Model& m, double optimal_force) {
  std::vector<ActuatorSpec> specs;
  for (const auto& c : m.coordinates) {
    ActuatorSpec a;
    a.name = c.name + "_reserve";
    a.coordinate = c.name;
    a.optimal_force = optimal_force;
    specs.push_back(a);
  }
  return specs;
}
}  // namespace

TEST(StaticOptimization, CoordinateActuatorsAloneCarryTheInverseDynamics) {
  const Model& m = walker();
  const auto synth = fixtures::synthesize_trial(m, {});
  const Storage coords = make_storage("coordinates", coordinate_names(m), synth.markers.time_s, synth.q, false);
  Model bare = without_muscles(m);
  for (auto& c : bare.coordinates) c.locked = false;  // ID knows no locks; SO, as OpenSim's, holds them
  const std::vector<ActuatorSpec> specs = reserves(m, 100);
  const ResolvedActuators acts(bare, specs);
  const StaticOptimizationResult r = static_optimization(bare, coords, nullptr, acts);
  const InverseDynamicsResult id = inverse_dynamics(bare, coords, nullptr);
  ASSERT_EQ(r.controls.rows(), id.generalized_forces.rows());
  EXPECT_LT((r.forces - id.generalized_forces).cwiseAbs().maxCoeff(), 1e-7);
  EXPECT_LT((r.controls * 100 - id.generalized_forces).cwiseAbs().maxCoeff(), 1e-7);

  // The walker's lumbar_rotation is locked: static optimization balances the other coordinates only
  // (OpenSim's SO keeps no equation for a constrained coordinate), so its own actuator rests.
  const Model locked = without_muscles(m);
  const int lr = locked.coordinate_index("lumbar_rotation");
  ASSERT_TRUE(locked.coordinates[lr].locked);
  const StaticOptimizationResult rl = static_optimization(locked, coords, nullptr, ResolvedActuators(locked, specs));
  EXPECT_LT(rl.forces.col(lr).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(rl.summary.frames_not_converged, 0);
}

// Two actuators on one coordinate share its load as the exponent prescribes: minimising
// c1^p + c2^p with F1 c1 + F2 c2 = tau gives c2 / c1 = (F2 / F1)^(1 / (p - 1)).
TEST(StaticOptimization, TwoActuatorsShareALoadAsTheExponentPrescribes) {
  const Model& m = walker();
  const auto synth = fixtures::synthesize_trial(m, {});
  const Storage coords = make_storage("coordinates", coordinate_names(m), synth.markers.time_s, synth.q, false);
  const Model bare = without_muscles(m);
  std::vector<ActuatorSpec> specs = reserves(m, 100);
  ActuatorSpec strong = specs[static_cast<std::size_t>(m.coordinate_index("knee_angle_r"))];
  strong.name = "knee_angle_r_strong";
  strong.optimal_force = 300;
  specs.push_back(strong);
  const ResolvedActuators acts(bare, specs);
  const int weak = m.coordinate_index("knee_angle_r"), strong_col = static_cast<int>(specs.size()) - 1;
  for (double p : {2.0, 3.0}) {
    StaticOptimizationOptions o;
    o.activation_exponent = p;
    const StaticOptimizationResult r = static_optimization(bare, coords, nullptr, acts, o);
    int frames = 0;
    double worst = 0;
    for (Eigen::Index i = 0; i < r.controls.rows(); ++i) {
      if (std::abs(r.controls(i, weak)) < 1e-3) continue;
      // A 1 % change of p moves the ratio 2 %; the solver leaves ~1e-11 (measured 7e-12 at p = 3 once its
      // stopping and line-search tests were made per variable: before, small variables stopped 0.3 % short).
      const double ratio = r.controls(i, strong_col) / r.controls(i, weak);
      EXPECT_NEAR(ratio, std::pow(3.0, 1 / (p - 1)), 1e-8) << "p = " << p << ", frame " << i << ": " << r.controls(i, weak);
      worst = std::max(worst, std::abs(ratio - std::pow(3.0, 1 / (p - 1))));
      ++frames;
    }
    std::printf("[ info ] p = %.0f: control ratio within %.1e of (F2 / F1)^(1 / (p - 1)) over %d frames\n", p, worst, frames);
    EXPECT_GT(frames, 20) << "p = " << p;
  }
}

TEST(StaticOptimization, MusclesWithReservesMeetTheEqualityWithinBounds) {
  const Model& m = walker();
  const auto synth = fixtures::synthesize_trial(m, {});
  const Storage coords = make_storage("coordinates", coordinate_names(m), synth.markers.time_s, synth.q, false);
  const ResolvedActuators acts(m, reserves(m, 10));  // weak: muscles should do what they can
  StaticOptimizationOptions o;
  o.step_interval = 5;
  const StaticOptimizationResult r = static_optimization(m, coords, nullptr, acts, o);
  // Every 5th sample from the first, and the last one, as OpenSim's AnalyzeTool records.
  const int samples = coords.num_rows();
  ASSERT_EQ(static_cast<int>(r.time_s.size()), (samples - 1) / 5 + 1 + ((samples - 1) % 5 != 0));
  EXPECT_DOUBLE_EQ(r.time_s[1] - r.time_s[0], coords.time()[5] - coords.time()[0]);
  EXPECT_DOUBLE_EQ(r.time_s.back(), coords.time()[samples - 1]);
  EXPECT_EQ(r.summary.frames_not_converged, 0);
  EXPECT_LT(r.summary.max_equality_violation, 1e-6);
  const int nm = static_cast<int>(m.muscles.size());
  EXPECT_GE(r.controls.leftCols(nm).minCoeff(), m.muscles[0].min_control - 1e-12);
  EXPECT_LE(r.controls.leftCols(nm).maxCoeff(), 1.0 + 1e-12);
  EXPECT_GT(r.controls.leftCols(nm).maxCoeff(), 0.05);  // muscles are used
}

TEST(Actuators, PointAndTorqueActuatorsActThroughTheJacobian) {
  const Model& m = walker();
  std::vector<ActuatorSpec> specs(2);
  specs[0].name = "push";
  specs[0].kind = ActuatorSpec::Kind::kPoint;
  specs[0].body = "tibia_r";
  specs[0].point = Eigen::Vector3d(0.01, -0.2, 0.02);
  specs[0].direction = Eigen::Vector3d(0, 0, 1);
  specs[0].force_is_global = true;
  specs[0].optimal_force = 50;
  specs[1].name = "twist";
  specs[1].kind = ActuatorSpec::Kind::kTorque;
  specs[1].body_a = "pelvis";
  specs[1].body_b = "ground";
  specs[1].axis = Eigen::Vector3d(0, 1, 0);
  specs[1].optimal_force = 20;
  const ResolvedActuators acts(m, specs);
  std::mt19937 rng(2);
  Eigen::VectorXd q = Eigen::VectorXd::Random(m.num_coordinates()) * 0.4, zero = Eigen::VectorXd::Zero(m.num_coordinates());
  KinematicsWorkspace<double> ws(m);
  MotionSubspace S(m);
  forward_kinematics(m, q.data(), ws);
  motion_subspace(m, q.data(), ws, S);
  Eigen::MatrixXd G(m.num_coordinates(), 2);
  acts.generalized_forces(m, q.data(), ws, S, G);
  // Same forces applied as external loads change RNEA's result by exactly -G.
  DynamicsWorkspace dws(m);
  Eigen::VectorXd tau0(m.num_coordinates()), tau1(m.num_coordinates());
  rnea(m, q.data(), zero.data(), zero.data(), no_loads, dws, tau0.data());
  std::vector<Vector6d> ext(m.bodies.size(), Vector6d::Zero());
  const auto& T = ws.body_in_ground[m.body_index("tibia_r")];
  ext[m.body_index("tibia_r")] = spatial_force(Eigen::Vector3d(0, 0, 50), T.rotation * specs[0].point + T.translation_m);
  ext[m.body_index("pelvis")] = spatial_force(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 20, 0));
  rnea(m, q.data(), zero.data(), zero.data(), ext, dws, tau1.data());
  EXPECT_LT((tau0 - tau1 - G.col(0) - G.col(1)).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_DOUBLE_EQ(G(m.coordinate_index("knee_angle_l"), 0), 0.0);  // other leg untouched
}

// leg6dof9musc's patella follows the knee (a CoordinateCouplerConstraint): static optimization
// balances moments on the free coordinates only, with the patella's share carried through the
// coupler, as OpenSim's does. Treated as an ordinary coordinate, the patella's own row (the
// quadriceps pulling on it, nothing else acting) cannot be met at any frame.
TEST(StaticOptimization, CoupledCoordinateIsBalancedThroughItsCoupler) {
  const std::string dir = refdata::shared_path("opensim/opensim-core-tests/CMC/");
  for (const char* f : {"leg6dof9musc.osim", "leg69_IK_swing.mot", "leg69_CMC_residuals_motors.xml"}) REQUIRE_REFERENCE(dir + f);
  const Model m = read_osim(dir + "leg6dof9musc.osim").model;
  ASSERT_EQ(m.couplers.size(), 1u);
  const Storage coords = read_storage(dir + "leg69_IK_swing.mot");
  const ResolvedActuators acts(m, read_actuators(dir + "leg69_CMC_residuals_motors.xml"));
  StaticOptimizationOptions o;
  o.lowpass_cutoff_hz = 6;
  const StaticOptimizationResult r = static_optimization(m, coords, nullptr, acts, o);
  std::printf("coupled SO: %d frames, %d not converged, largest violation %.1e\n", r.summary.frames,
              r.summary.frames_not_converged, r.summary.max_equality_violation);
  EXPECT_GT(r.summary.frames, 25);
  EXPECT_EQ(r.summary.frames_not_converged, 0);
  EXPECT_LT(r.summary.max_equality_violation, 1e-6);
  // The vastus, which pulls only on the patella, still works: the coupler carries its force to the knee.
  const int vas = std::find(r.names.begin(), r.names.end(), "vas_int_r") - r.names.begin();
  ASSERT_LT(vas, static_cast<int>(r.names.size()));
  EXPECT_GT(r.forces.col(vas).maxCoeff(), 1.0);

  Model uncoupled = m;
  uncoupled.couplers.clear();
  const ResolvedActuators acts2(uncoupled, read_actuators(dir + "leg69_CMC_residuals_motors.xml"));
  const StaticOptimizationResult u = static_optimization(uncoupled, coords, nullptr, acts2, o);
  EXPECT_EQ(u.summary.frames_not_converged, u.summary.frames);
}
