// Forward simulation pieces (Dormand-Prince, compliant tendons, the muscle-driven model) and CMC
// on the fixture walker.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <tuple>

#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/dynamics/dormand_prince.h"
#include "cpgait/dynamics/forward_simulation.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/millard2012.h"
#include "cpgait/muscles/muscle_model.h"
#include "cpgait/muscles/thelen2003.h"
#include "test_support.h"

using namespace cpgait;

using refdata::walker;

TEST(DormandPrince, HarmonicOscillatorToTolerance) {
  const OdeFunction f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    dx[0] = x[1];
    dx[1] = -x[0];
  };
  for (double tol : {1e-4, 1e-8}) {
    Eigen::VectorXd x(2);
    x << 1.0, 0.0;
    DormandPrinceOptions o;
    o.relative_tolerance = o.absolute_tolerance = tol;
    o.max_step_s = 1.0;
    const auto s = integrate_dormand_prince(f, 0.0, 2 * M_PI, x, o);
    ASSERT_TRUE(s.success) << s.message;
    EXPECT_NEAR(x[0], 1.0, 50 * tol);
    EXPECT_NEAR(x[1], 0.0, 50 * tol);
    if (tol == 1e-8) {
      EXPECT_GT(s.accepted_steps, 40);  // the error control did tighten the steps
    }
  }
}

TEST(DormandPrince, StiffDecayStaysStableAndSaysHowManySteps) {
  // lambda = -1e4: an explicit method must keep h * lambda inside its stability region (~3.3);
  // the controller finds that without being told.
  const OdeFunction f = [](double t, const Eigen::VectorXd& x, Eigen::VectorXd& dx) { dx[0] = -1e4 * (x[0] - std::cos(t)); };
  Eigen::VectorXd x(1);
  x << 0.0;
  const auto s = integrate_dormand_prince(f, 0.0, 1.0, x, {});
  ASSERT_TRUE(s.success);
  EXPECT_NEAR(x[0], std::cos(1.0), 1e-3);
  EXPECT_GT(s.accepted_steps, 2000);  // ~1 s / 3.3e-4 s
}

namespace {
// y1' = lambda (y1 - y2), y2' = -y2 (lambda = -1e4): after a 1e-4 s transient y1 follows
// y2 = exp(-t), with its exact Jacobian for the W-methods.
struct StiffPair {
  static constexpr double lambda = -1e4;
  OdeFunction f = [](double, const Eigen::VectorXd& x, Eigen::VectorXd& dx) {
    dx.resize(2);
    dx[0] = lambda * (x[0] - x[1]);
    dx[1] = -x[1];
  };
  WPrepare prepare = [this](double t, const Eigen::VectorXd& x, Eigen::VectorXd& f0) { f(t, x, f0); };
  WSolve solve = [](double gh, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) {
    k.resize(2);
    k[1] = rhs[1] / (1.0 + gh);                                // row 2: (1 + gh) k2 = r2
    k[0] = (rhs[0] - gh * lambda * k[1]) / (1.0 - gh * lambda);  // row 1: (1 - gh l) k1 + gh l k2 = r1
  };
};

// A W-method's error at t = 1 from y(0) = 1 with fixed 0.1 s steps over that with 0.05 s: 2^order.
template <typename Integrate>
double halving_error_ratio(Integrate integrate, const OdeFunction& g, const WSolve& solve, double exact) {
  const WPrepare prepare = [&](double t, const Eigen::VectorXd& y, Eigen::VectorXd& f0) { g(t, y, f0); };
  double err[2];
  for (int i = 0; i < 2; ++i) {
    RosenbrockOptions fixed;
    fixed.relative_tolerance = fixed.absolute_tolerance = 1e6;  // no step control: fixed steps
    fixed.initial_step_s = fixed.max_step_s = 0.1 / (1 << i);
    Eigen::VectorXd y(1);
    y << 1.0;
    integrate(g, prepare, solve, 0.0, 1.0, y, fixed, WStepDone());
    err[i] = std::abs(y[0] - exact);
  }
  return err[0] / err[1];
}
}  // namespace

TEST(RosenbrockW, SecondOrderAndStableOnStiffModes) {
  // With the exact Jacobian the steps are set by accuracy, not by the stiff time constant.
  const StiffPair pair;
  const auto& [f, prepare, solve] = std::tie(pair.f, pair.prepare, pair.solve);
  Eigen::VectorXd x(2);
  x << 0.0, 1.0;
  RosenbrockOptions o;
  o.relative_tolerance = o.absolute_tolerance = 1e-6;
  o.max_step_s = 1.0;
  // Every accepted step is reported once, end to end from t0 to t1, with the state it ended in.
  long reported = 0;
  double t_reached = 0.0;
  Eigen::VectorXd x_reached = x;
  const WStepDone step_done = [&](double ta, const Eigen::VectorXd& xa, double tb, const Eigen::VectorXd& xb) {
    EXPECT_EQ(ta, t_reached);
    EXPECT_EQ(xa, x_reached);
    EXPECT_GT(tb, ta);
    t_reached = tb;
    x_reached = xb;
    ++reported;
  };
  const auto s = integrate_ros2(f, prepare, solve, 0.0, 2.0, x, o, step_done);
  ASSERT_TRUE(s.success) << s.message;
  EXPECT_NEAR(x[1], std::exp(-2.0), 1e-4);
  EXPECT_NEAR(x[0], std::exp(-2.0), 1e-4);
  EXPECT_EQ(reported, s.accepted_steps);
  EXPECT_EQ(t_reached, 2.0);
  EXPECT_EQ(x_reached, x);
  // Dormand-Prince at the same tolerance is held to its stability bound (h < 3.3e-4 s).
  Eigen::VectorXd x_explicit(2);
  x_explicit << 0.0, 1.0;
  DormandPrinceOptions e;
  e.relative_tolerance = e.absolute_tolerance = 1e-6;
  e.max_step_s = 1.0;
  const auto se = integrate_dormand_prince(f, 0.0, 2.0, x_explicit, e);
  EXPECT_GT(se.accepted_steps, 6000);
  EXPECT_LT(s.accepted_steps, se.accepted_steps / 2);
  // Order two on a non-stiff problem even with a crude Jacobian (zero): halving the step quarters
  // the error.
  const OdeFunction g = [](double, const Eigen::VectorXd& y, Eigen::VectorXd& dy) { dy = -y; };
  const WSolve zero_j = [](double, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) { k = rhs; };
  EXPECT_NEAR(halving_error_ratio(integrate_ros2, g, zero_j, std::exp(-1.0)), 4.0, 0.6);
}

// CMC's default integrator (ComputedMuscleControlOptions). Measured against ROS2 at its 1e-3, with
// the same W (2026-11-26, this machine):
//   gait10dof18musc pErr RMS (deg)   ankle_r  ankle_l  knee_r   knee_l
//     ROS2 1e-3                      0.0459   0.0332   0.0667   0.0629
//     ROS34PW2 1e-4                  0.0343   0.0240   0.0689   0.0647
//     ROS34PW2 1.5e-4                0.0391   0.0271   0.0677   0.0650
//     ROS34PW2 2e-4                  0.0408   0.0299   0.0672   0.0655
//     ROS34PW2 3e-4                  0.0652   0.0476   0.0681   0.0669
//   subject01 (gait2392, 1.46 s)     steps  evaluations  instructions  against ROS2 at 1e-5: pErr RMS
//                                                                      max diff, force rel. RMS, q max diff
//     ROS2 1e-3                      4217   8700         2.88e9        1.25 deg, 0.184, 17.8 deg
//     ROS34PW2 2e-4                  1189   5794         2.05e9        0.24 deg, 0.152, 13.8 deg
//     ROS34PW2 1e-5 (the floor: ROS2 and ROS34PW2 at 1e-5 disagree by)   0.58 deg, 0.123,  7.4 deg
// (subject01's mtp is chaotic under CMC: no two tolerances agree there to better than degrees.)
TEST(RosenbrockW, Ros34pw2ThirdOrderWithAnyJacobianAndStableOnStiffModes) {
  // The stiff pair: with the exact Jacobian, accurate and in fewer steps than ROS2 at the same
  // tolerance (its error estimate is of second order, ROS2's of first).
  const StiffPair pair;
  const auto& [f, prepare, solve] = std::tie(pair.f, pair.prepare, pair.solve);
  const double lambda = StiffPair::lambda;
  RosenbrockOptions o;
  o.relative_tolerance = o.absolute_tolerance = 1e-6;
  o.max_step_s = 1.0;
  Eigen::VectorXd x(2), x2(2);
  x << 0.0, 1.0;
  x2 = x;
  long reported = 0;
  double t_reached = 0.0;
  const WStepDone step_done = [&](double ta, const Eigen::VectorXd&, double tb, const Eigen::VectorXd&) {
    EXPECT_EQ(ta, t_reached);
    t_reached = tb;
    ++reported;
  };
  const auto s = integrate_ros34pw2(f, prepare, solve, 0.0, 2.0, x, o, step_done);
  ASSERT_TRUE(s.success) << s.message;
  EXPECT_NEAR(x[1], std::exp(-2.0), 2e-6);
  EXPECT_NEAR(x[0], lambda / (lambda + 1.0) * std::exp(-2.0), 2e-6);  // y1 = y2 lambda / (lambda + 1) once the transient is gone
  EXPECT_EQ(reported, s.accepted_steps);
  EXPECT_EQ(t_reached, 2.0);
  const auto s2 = integrate_ros2(f, prepare, solve, 0.0, 2.0, x2, o);
  std::printf("[info] stiff pair at 1e-6: ROS34PW2 %ld steps (%ld evaluations), ROS2 %ld steps (%ld evaluations)\n", s.accepted_steps,
              s.evaluations, s2.accepted_steps, s2.evaluations);
  EXPECT_LT(s.evaluations, s2.evaluations / 2);
  // Order three on a non-autonomous problem whatever the Jacobian (zero, or half the true one):
  // halving the step divides the error by eight. y' = sin t - y, y(0) = 1.
  const OdeFunction g = [](double t, const Eigen::VectorXd& y, Eigen::VectorXd& dy) { dy = -y + Eigen::VectorXd::Constant(1, std::sin(t)); };
  const double exact = 0.5 * (std::sin(1.0) - std::cos(1.0)) + 1.5 * std::exp(-1.0);
  for (const double j : {0.0, -0.5}) {
    const WSolve approximate = [j](double gh, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) { k = rhs / (1.0 - gh * j); };
    EXPECT_NEAR(halving_error_ratio(integrate_ros34pw2, g, approximate, exact), 8.0, 1.5) << "J = " << j;
  }
}

// The reproduced gait's fast option: equal steps of at most max_step_s ending at t1, one evaluation
// (prepare's) each, first order whatever J, and with the exact J stable on the stiff pair at steps
// 3,000 times its stiff time constant (explicit Euler's factor there would be |1 + h lambda| ~ 2,900).
TEST(RosenbrockW, LinearlyImplicitEulerFirstOrderOneEvaluationPerStepAndStable) {
  const StiffPair pair;
  RosenbrockOptions o;
  o.max_step_s = 0.3;  // 2 s in 7 equal steps of 2/7 s
  Eigen::VectorXd x(2);
  x << 0.0, 1.0;
  double t_reached = 0.0;
  long reported = 0;
  const WStepDone step_done = [&](double ta, const Eigen::VectorXd&, double tb, const Eigen::VectorXd&) {
    EXPECT_EQ(ta, t_reached);
    EXPECT_NEAR(tb - ta, 2.0 / 7.0, 1e-12);
    t_reached = tb;
    ++reported;
  };
  const auto s = integrate_w_method(WMethod::kLinearlyImplicitEuler, pair.f, pair.prepare, pair.solve, 0.0, 2.0, x, o, step_done);
  ASSERT_TRUE(s.success) << s.message;
  EXPECT_EQ(s.accepted_steps, 7);
  EXPECT_EQ(s.evaluations, 7);
  EXPECT_EQ(reported, 7);
  EXPECT_EQ(t_reached, 2.0);
  // With the exact J on a linear problem it is implicit Euler: y2 shrinks by 1 / (1 + h) a step, and
  // y1 follows it, as the exact y1 = y2 lambda / (lambda + 1) does.
  EXPECT_NEAR(x[1], std::pow(1.0 + 2.0 / 7.0, -7), 1e-12);
  EXPECT_NEAR(x[0], x[1], 1e-3 * x[1]);
  // First order whatever the Jacobian (zero: explicit Euler; half the true one): halving the step
  // halves the error. y' = sin t - y, y(0) = 1.
  const OdeFunction g = [](double t, const Eigen::VectorXd& y, Eigen::VectorXd& dy) { dy = -y + Eigen::VectorXd::Constant(1, std::sin(t)); };
  const double exact = 0.5 * (std::sin(1.0) - std::cos(1.0)) + 1.5 * std::exp(-1.0);
  for (const double j : {0.0, -0.5}) {
    const WSolve approximate = [j](double gh, const Eigen::VectorXd& rhs, Eigen::VectorXd& k) { k = rhs / (1.0 - gh * j); };
    EXPECT_NEAR(halving_error_ratio(integrate_linearly_implicit_euler, g, approximate, exact), 2.0, 0.3) << "J = " << j;
  }
  // Its name in options and files.
  EXPECT_EQ(w_method_named(w_method_name(WMethod::kLinearlyImplicitEuler)), WMethod::kLinearlyImplicitEuler);
  EXPECT_EQ(w_method_name(WMethod::kLinearlyImplicitEuler), "linearly_implicit_euler");
}

TEST(MuscleDrivenDynamics, StructuredWSolveInvertsItsJacobian) {
  // (I - gh J) k = rhs with J from finite differences of the stiff blocks: check W k against rhs
  // by applying J explicitly through the same blocks, for compliant and rigid tendons, and with the
  // feet pressing into sliding ground (contact damping and stiffness).
  const Model& m = walker();
  ContactSet feet = default_foot_contacts(m);
  // Variant 3: rigid tendons on sliding ground with the whole W (MuscleDrivenJacobian::whole_w).
  for (int variant = 0; variant < 4; ++variant) {
    const bool compliant = variant != 1 && variant != 3, contact = variant >= 2, whole = variant == 3;
    MuscleDrivenSystem sys;
    sys.model = &m;
    sys.compliant_tendons = compliant;
    if (contact) sys.contacts = &feet;
    MuscleDrivenWorkspace ws(sys);
    MuscleDrivenJacobian jac;
    jac.whole_w = whole;
    const int nq = m.num_coordinates(), nm = sys.num_muscles(), n = sys.state_size();
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n), f0(n), k(n), none(0);
    x.head(nq) = m.default_coordinates();
    for (int j = 0; j < nm; ++j) x[sys.activation_index(j)] = 0.3;
    if (compliant) {
      // Fibres in equilibrium: stretched tendons, whose stiffness couples the joints and fibres in W.
      Eigen::VectorXd xd(n);
      muscle_driven_derivatives(sys, 0.0, x, Eigen::VectorXd::Zero(nm), none, ws, xd);  // the paths at x
      for (int j = 0; j < nm; ++j)
        x[sys.fiber_length_index(j)] = muscles::compliant_equilibrium_fiber_length(m.muscles[j], 0.3, ws.geometry.length_m[j], 0.0);
    }
    if (contact) {
      // The ground 5 mm into the lowest sphere, moving backwards under it (a treadmill).
      KinematicsWorkspace<double> kws(m);
      forward_kinematics(m, x.data(), kws);
      double lowest = 1e9;
      for (const auto& s : feet.spheres)
        lowest = std::min(lowest, (kws.body_in_ground[s.body].rotation * s.location_m + kws.body_in_ground[s.body].translation_m).y() - s.radius_m);
      feet.ground_height_m = lowest + 0.005;
      feet.ground_velocity_m_s = {-0.05, 0, 0};
    }
    const Eigen::VectorXd u = Eigen::VectorXd::Constant(nm, 0.6);
    muscle_driven_prepare(sys, 0.0, x, u, none, ws, jac, f0);
    // Each muscle's crossed coordinates: exactly its nonzero moment arms, ascending.
    ASSERT_EQ(static_cast<int>(jac.crossed.size()), nm);
    for (int j = 0; j < nm; ++j) {
      std::vector<int> nonzero;
      for (int c = 0; c < nq; ++c)
        if (jac.moment_arm(j, c) != 0) nonzero.push_back(c);
      EXPECT_EQ(jac.crossed[j], nonzero) << m.muscles[j].name;
      EXPECT_FALSE(nonzero.empty()) << m.muscles[j].name;
    }
    if (contact) {
      ASSERT_EQ(jac.damping.rows(), nq);
      EXPECT_GT(jac.damping.trace(), 0.0);
      EXPECT_GT(jac.stiffness.trace(), 0.0);
      // Friction follows the normal force, which follows the normal speed: the whole damping is
      // unsymmetric; the Cholesky W keeps its symmetric, positive part.
      const double asymmetry = (jac.damping - jac.damping.transpose()).norm() / jac.damping.norm();
      if (whole) {
        EXPECT_GT(asymmetry, 1e-3);
        EXPECT_GT(jac.dF_dL.maxCoeff(), 0.0);  // the force-length curves' stiffness, in jac.stiffness
        // Without the contact terms the stiffness is the muscles' R^T diag(dF/dL) R alone, formed in
        // one pass with the damping's R^T diag(dF/dV) R: both as the dense products give them.
        MuscleDrivenSystem muscles_only = sys;
        muscles_only.contacts = nullptr;
        MuscleDrivenJacobian own;
        own.whole_w = true;
        muscle_driven_jacobian(muscles_only, x, u, ws, own, f0);
        const Eigen::MatrixXd& R = own.moment_arm;
        const Eigen::MatrixXd K = R.transpose() * own.dF_dL.asDiagonal() * R, D = R.transpose() * own.dF_dV.asDiagonal() * R;
        EXPECT_LT((own.stiffness - K).norm(), 1e-12 * K.norm());
        EXPECT_LT((own.muscle_damping - D).norm(), 1e-12 * D.norm());
        EXPECT_GT((jac.stiffness - own.stiffness).trace(), 0.0);  // the contact's share
      } else {
        EXPECT_LT(asymmetry, 1e-12);
        EXPECT_GE(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(jac.damping).eigenvalues().minCoeff(), -1e-9);
      }
    }
    const Eigen::VectorXd rhs = Eigen::VectorXd::Random(n);
    const double gh = 2e-3;
    muscle_driven_w_solve(sys, jac, gh, rhs, k);
    if (whole) {
      EXPECT_TRUE(jac.lu.sparse()) << "the whole W is on the tree's pattern, its symmetric part definite";
    }
    // Apply W = I - gh J block by block.
    Eigen::VectorXd Wk = k;
    Wk.head(nq) -= gh * k.segment(nq, nq);
    Eigen::VectorXd g(nm);
    const Eigen::VectorXd dL = -jac.moment_arm * k.head(nq);  // the paths' stretch by the joints' motion
    int coupled = 0;
    for (int j = 0; j < nm; ++j) {
      const int ia = sys.activation_index(j);
      Wk[ia] -= gh * jac.da_da[j] * k[ia];
      if (compliant) {
        // The tendon's coupling to the joints, kept where its effective stiffness is positive.
        const bool kept = jac.tendon_stiffness[j] > 0;
        coupled += kept;
        const int il = sys.fiber_length_index(j);
        Wk[il] -= gh * (jac.dl_dl[j] * k[il] + jac.dl_da[j] * k[ia] + (kept ? jac.dl_dL[j] * dL[j] : 0.0));
        g[j] = jac.dF_dl[j] * k[il] + (kept ? jac.dF_dL[j] * dL[j] : 0.0);
      } else {
        g[j] = jac.dF_da[j] * k[ia];
      }
    }
    Eigen::VectorXd Ju = jac.moment_arm.transpose() * g;
    if (!compliant) Ju -= jac.moment_arm.transpose() * (jac.dF_dV.asDiagonal() * (jac.moment_arm * k.segment(nq, nq)));
    if (contact) Ju -= jac.damping * k.segment(nq, nq) + jac.stiffness * k.head(nq);
    Wk.segment(nq, nq) -= gh * jac.M.llt().solve(Ju);
    EXPECT_LT((Wk - rhs).cwiseAbs().maxCoeff(), 1e-9) << "variant " << variant;
    if (compliant) {
      // Every stretched tendon is coupled to the joints (the walker's default pose leaves some slack),
      // and its longer fibre shortens faster: the stiff, stable mode.
      int stretched = 0;
      for (int j = 0; j < nm; ++j)
        if (ws.muscle_force_N[j] > 0) {
          ++stretched;
          EXPECT_LT(jac.dl_dl[j], 0.0) << j;
          EXPECT_GT(jac.dF_dL[j], 0.0) << j;
          EXPECT_GT(jac.tendon_stiffness[j], 0.0) << j;
        }
      EXPECT_GT(stretched, 0);
      EXPECT_EQ(coupled, stretched);
    }
  }
}

TEST(Thelen2003, CompliantEquilibriumBalancesTendonAndFibre) {
  const Muscle& mu = walker().muscles[0];
  const double L = mu.tendon_slack_length_m + mu.optimal_fiber_length_m * 1.05;
  for (double a : {0.02, 0.5, 1.0}) {
    const double lm = thelen2003::compliant_equilibrium_fiber_length(mu, a, L, 0.0);
    const auto f = thelen2003::compliant_tendon_fiber(mu, a, L, lm);
    // At equilibrium the fibre does not move, and the tendon carries what the fibre pulls.
    EXPECT_NEAR(f.fiber_velocity_m_s, 0.0, 1e-6 * mu.optimal_fiber_length_m * mu.max_contraction_velocity) << a;
    const double fibre = thelen2003::active_fiber_force_along_tendon(mu, a, lm, 0.0) +
                         thelen2003::passive_fiber_force_along_tendon(mu, lm);
    EXPECT_NEAR(f.force_N, fibre, 1e-6 * mu.max_isometric_force_N) << a;
    // The tendon stretches under load, so the fibre is shorter than with a rigid tendon.
    EXPECT_LT(lm, thelen2003::rigid_tendon_fiber(mu, L, 0).fiber_length_m) << a;
  }
  // More activation, more force at the same length; a fibre longer than equilibrium shortens.
  const double lm = thelen2003::compliant_equilibrium_fiber_length(mu, 0.5, L, 0.0);
  EXPECT_GT(thelen2003::compliant_tendon_fiber(mu, 1.0, L, lm).force_N, 0.0);
  EXPECT_LT(thelen2003::compliant_tendon_fiber(mu, 1.0, L, lm).fiber_velocity_m_s, 0.0);  // more activation: shortens
  EXPECT_LT(thelen2003::compliant_tendon_fiber(mu, 0.5, L, lm * 1.02).fiber_velocity_m_s, 0.0);
  EXPECT_GT(thelen2003::compliant_tendon_fiber(mu, 0.5, L, lm * 0.98).fiber_velocity_m_s, 0.0);
}

// CMC's force predictor: n substeps of BDF2 (backward Euler on the first) with a linearly moving path,
// each solved by bisection on its monotonic residual g(l) = l - base - c h v(l).
CompliantMuscleState predictor_by_bisection(const Muscle& mu, double a0, double lm0, double L0, double dL, double u, double T,
                                            int n, bool bdf2) {
  double a = a0, lm = lm0, lm_prev = lm0;
  const double h = T / n;
  const double lm_min = mu.millard ? millard2012::min_fiber_length(mu) : thelen2003::min_fiber_length(mu);
  for (int i = 1; i <= n; ++i) {
    a = thelen_activation_after(mu, a, u, h);
    const double L = L0 + dL * i / n;
    const bool first = i == 1 || !bdf2;
    const double base = first ? lm : (4 * lm - lm_prev) / 3, ch = first ? h : 2 * h / 3;
    auto g = [&](double l) { return l - base - ch * muscles::compliant_tendon_fiber(mu, a, L, l).fiber_velocity_m_s; };
    double lo = lm_min, hi = 2 * lm + mu.optimal_fiber_length_m;
    lm_prev = lm;
    if (g(lo) >= 0) {
      lm = lo;
      continue;
    }
    for (int it = 0; it < 200; ++it) (g(0.5 * (lo + hi)) < 0 ? lo : hi) = 0.5 * (lo + hi);
    lm = 0.5 * (lo + hi);
  }
  return {a, lm, muscles::compliant_tendon_fiber(mu, a, L0 + dL, lm).force_N};
}

// The predictor solves each BDF2 substep (three of 5 ms / 3 in a 5 ms window) to its root, with or
// without a start handed over from an earlier call, for a Thelen and a Millard muscle, from rest and
// while the path moves. BDF2 is second order: on three substeps its forces are closer to the
// converged ones (400 substeps) than backward Euler's on five 1 ms substeps, which the predictor
// used before (worst case 5.9 against 6.6 N for Thelen, 6.1 against 9.1 N for Millard; backward Euler
// on three substeps is further off than on five).
TEST(CompliantMuscleAfter, SolvesEachBdf2SubstepToItsRoot) {
  Muscle millard = walker().muscles[0];
  millard.millard = std::make_shared<const millard2012::Curves>(millard2012::make_curves(millard2012::Parameters{}));
  for (const Muscle* mu : {&walker().muscles[0], static_cast<const Muscle*>(&millard)}) {
    const double L0 = mu->tendon_slack_length_m + mu->optimal_fiber_length_m * 1.02, T = 0.005;
    double worst_bdf2 = 0, worst_euler = 0;
    for (double a0 : {0.02, 0.3}) {
      const double lm0 = muscles::compliant_equilibrium_fiber_length(*mu, a0, L0, 0.0);
      for (double dL : {-0.004, 0.0, 0.003}) {
        muscles::PredictorStart start;
        for (double u : {0.01, 0.4, 1.0}) {
          const auto got = muscles::compliant_muscle_after(*mu, a0, lm0, L0, L0 + dL, u, T);
          const auto got_started = muscles::compliant_muscle_after(*mu, a0, lm0, L0, L0 + dL, u, T, &start);
          const auto ref = predictor_by_bisection(*mu, a0, lm0, L0, dL, u, T, 3, true);
          const std::string what = std::string(mu->millard ? "Millard" : "Thelen") + " a0 " + std::to_string(a0) +
                                   " dL " + std::to_string(dL) + " u " + std::to_string(u);
          for (const auto& r : {got, got_started}) {
            EXPECT_NEAR(r.fiber_length_m, ref.fiber_length_m, 1e-10 * mu->optimal_fiber_length_m) << what;
            EXPECT_NEAR(r.force_N, ref.force_N, 1e-6 * mu->max_isometric_force_N) << what;
            EXPECT_NEAR(r.activation, ref.activation, 1e-15) << what;
          }
          const double converged = predictor_by_bisection(*mu, a0, lm0, L0, dL, u, T, 400, true).force_N;
          worst_bdf2 = std::max(worst_bdf2, std::abs(got.force_N - converged));
          worst_euler = std::max(worst_euler, std::abs(predictor_by_bisection(*mu, a0, lm0, L0, dL, u, T, 5, false).force_N - converged));
        }
        // Thelen's secant stores its slope for the next call; Millard's substeps are one Newton
        // (millard2012::implicit_fiber_step) and need none.
        if (!mu->millard) {
          EXPECT_TRUE(std::isfinite(start.velocity_slope_per_s) && start.velocity_slope_per_s <= 0);
        }
      }
    }
    EXPECT_LT(worst_bdf2, worst_euler) << (mu->millard ? "Millard" : "Thelen");
    std::printf("[ info ] %s: predictor force error vs 400 substeps: BDF2 x3 %.3g N, backward Euler x5 %.3g N\n",
                mu->millard ? "Millard" : "Thelen", worst_bdf2, worst_euler);
  }
}

TEST(ActivationDynamics, ExcitationForATargetActivation) {
  const Muscle& mu = walker().muscles[0];
  for (double target : {0.095, 0.2, 0.4}) {  // reachable from 0.1 within 10 ms
    const double u = thelen_excitation_for(mu, 0.1, target, 0.01, 0.02, 1.0);
    EXPECT_NEAR(thelen_activation_after(mu, 0.1, u, 0.01), target, 1e-5) << target;
  }
  // Out of reach within the window: the bound is returned.
  EXPECT_DOUBLE_EQ(thelen_excitation_for(mu, 0.1, 0.99, 0.01, 0.02, 1.0), 1.0);
}

TEST(MuscleDrivenDynamics, WithoutMusclesItIsForwardDynamics) {
  const Model& m = walker();
  Model bare = m;
  bare.muscles.clear();
  for (auto& c : bare.coordinates) c.locked = false;  // plain forward dynamics knows no locks
  MuscleDrivenSystem sys;
  sys.model = &bare;
  MuscleDrivenWorkspace ws(sys);
  std::mt19937 rng(3);
  const int nq = m.num_coordinates();
  Eigen::VectorXd x(sys.state_size()), dx(sys.state_size());
  x.head(nq) = refdata::random_pose(m, rng, 1.0);
  x.tail(nq) = Eigen::VectorXd::Random(nq);
  Eigen::VectorXd none(0);
  muscle_driven_derivatives(sys, 0.0, x, none, none, ws, dx);
  ForwardDynamicsWorkspace fws(bare);
  Eigen::VectorXd qdd(nq), tau = Eigen::VectorXd::Zero(nq);
  forward_dynamics(bare, x.data(), x.data() + nq, tau.data(), {}, fws, qdd.data());
  EXPECT_LT((dx.tail(nq) - qdd).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((dx.head(nq) - x.tail(nq)).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(MuscleDrivenDynamics, MuscleForceActsThroughItsMomentArms) {
  Model m = walker();
  for (auto& c : m.coordinates) c.locked = false;  // every coordinate free to take its moment
  MuscleDrivenSystem sys;
  sys.model = &m;
  sys.compliant_tendons = false;
  MuscleDrivenWorkspace ws(sys);
  const int nq = m.num_coordinates(), nm = sys.num_muscles();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), dx(sys.state_size()), dx_off(sys.state_size());
  x.head(nq) = m.default_coordinates();
  Eigen::VectorXd u = Eigen::VectorXd::Constant(nm, 0.5), none(0);
  x.tail(nm).setConstant(0.01);
  muscle_driven_derivatives(sys, 0.0, x, u, none, ws, dx_off);
  x[sys.activation_index(0)] = 1.0;
  muscle_driven_derivatives(sys, 0.0, x, u, none, ws, dx);
  // The extra generalized force of muscle 0 is r^T dF; M times the change in accelerations equals it.
  const Eigen::VectorXd dqdd = dx.segment(nq, nq) - dx_off.segment(nq, nq);
  const double dF = thelen2003::rigid_tendon_active_force(m.muscles[0], 1.0, ws.geometry.length_m[0], 0.0) -
                    thelen2003::rigid_tendon_active_force(m.muscles[0], 0.01, ws.geometry.length_m[0], 0.0);
  EXPECT_LT((ws.fd.M * dqdd - ws.geometry.moment_arm_m.row(0).transpose() * dF).cwiseAbs().maxCoeff(), 1e-8);
  // Activation rises toward the excitation.
  EXPECT_GT(dx_off[sys.activation_index(1)], 0.0);
  EXPECT_LT(dx[sys.activation_index(0)], 0.0);
}

namespace {
struct WalkerCmc {
  Storage kinematics;
  std::vector<ActuatorSpec> specs;
  std::vector<CmcJointTask> tasks;
};
WalkerCmc walker_cmc_inputs() {
  const Model& m = walker();
  fixtures::SyntheticTrialOptions o;
  o.rate_hz = 200;
  o.duration_s = 1.2;
  const auto trial = fixtures::synthesize_trial(m, o);
  WalkerCmc in;
  std::vector<double> t(trial.q.rows());
  for (int i = 0; i < trial.q.rows(); ++i) t[i] = i / o.rate_hz;
  in.kinematics = make_storage("walker.sto", coordinate_names(m), t, trial.q, false);
  for (const auto& c : m.coordinates) {
    ActuatorSpec a;
    a.name = c.name + "_reserve";
    a.coordinate = c.name;
    a.optimal_force = c.joint == 0 ? 1000.0 : 10.0;  // residuals carry the body: no ground forces here
    in.specs.push_back(a);
    CmcJointTask task;
    task.name = task.coordinate = c.name;
    in.tasks.push_back(task);
  }
  return in;
}
}  // namespace

TEST(ComputedMuscleControl, TracksSyntheticWalkerKinematics) {
  const Model& m = walker();
  const WalkerCmc in = walker_cmc_inputs();
  const ResolvedActuators actuators(m, in.specs);
  for (int variant = 0; variant < 3; ++variant) {
    const bool refresh = variant == 1;
    ComputedMuscleControlOptions o;
    o.time_range_s = std::make_pair(0.1, 1.0);
    o.refresh_actuators = refresh;
    if (variant == 2) o.integrator = CmcIntegrator::kDormandPrince;  // the explicit reference
    const auto r = computed_muscle_control(m, in.kinematics, nullptr, nullptr, actuators, in.tasks, nullptr, o);
    EXPECT_EQ(r.summary.windows_infeasible, 0) << "variant " << variant << ": " << r.summary.BriefReport();
    EXPECT_EQ(r.summary.external_forces, "none");
    const Eigen::VectorXd rms = r.position_error_rms();
    for (int c = 0; c < m.num_coordinates(); ++c) {
      const double limit = m.coordinates[c].is_angle() ? 0.5 * M_PI / 180 : 0.002;
      EXPECT_LT(rms[c], limit) << m.coordinates[c].name << " variant " << variant;
    }
    // The muscles do work (the knee extensors, at least, well above their floor), and every
    // excitation stays inside its range.
    EXPECT_GT(r.activation.col(0).maxCoeff(), 0.1) << m.muscles[0].name;
    for (int k = 0; k < static_cast<int>(m.muscles.size()); ++k) {
      EXPECT_GE(r.controls.col(k).minCoeff(), m.muscles[k].min_control - 1e-12);
      EXPECT_LE(r.controls.col(k).maxCoeff(), m.muscles[k].max_control + 1e-12);
    }
    EXPECT_NEAR(r.time_s.front(), 0.1, 1e-9);
    EXPECT_NEAR(r.time_s.back(), 1.0, 1e-6);
    // A record at every output interval, whether the integrator stops there (refresh, Dormand-Prince)
    // or steps across and the record is interpolated (the default).
    ASSERT_EQ(r.time_s.size(), 901u) << "variant " << variant;
    for (std::size_t i = 1; i < r.time_s.size(); ++i) ASSERT_NEAR(r.time_s[i] - r.time_s[i - 1], o.output_interval_s, 1e-9) << i;
    // The interpolated records lie on the integrated path: the q recorded at each window's start
    // (an integrated state) against the straight line through its neighbours 1 ms away differs by
    // no more than q's curvature allows (|q''| h^2 / 2 with q'' < 100 rad/s^2 here).
    for (std::size_t i = 10; i + 1 < r.time_s.size(); i += 10)
      for (int c = 0; c < m.num_coordinates(); ++c)
        EXPECT_LT(std::abs(r.q(i, c) - 0.5 * (r.q(i - 1, c) + r.q(i + 1, c))), 100 * 1e-6 / 2) << i << " " << c;
    if (variant == 0) {
      // Records between steps take their muscle forces from the step's ends: against an evaluation
      // at the recorded state, the same within a small share of each muscle's peak force.
      MuscleDrivenSystem sys;
      sys.model = &m;
      MuscleDrivenWorkspace ws(sys);
      const int nm = sys.num_muscles();
      Eigen::VectorXd x(sys.state_size()), xdot(sys.state_size());
      std::vector<double> differences;
      for (std::size_t i = 0; i < r.time_s.size(); ++i) {
        x << r.q.row(i).transpose(), r.u.row(i).transpose(), r.activation.row(i).transpose(), r.fiber_length_m.row(i).transpose();
        muscle_driven_derivatives(sys, r.time_s[i], x, Eigen::VectorXd::Zero(nm), Eigen::VectorXd(), ws, xdot);
        for (int k = 0; k < nm; ++k)
          differences.push_back(std::abs(ws.muscle_force_N[k] - r.muscle_force_N(i, k)) / (1.0 + r.muscle_force_N.col(k).cwiseAbs().maxCoeff()));
      }
      std::sort(differences.begin(), differences.end());
      const double median = differences[differences.size() / 2], p99 = differences[differences.size() * 99 / 100];
      std::printf("[info] recorded muscle forces against an evaluation at the recorded state: median %.1e, 99th percentile %.1e, largest %.1e of the peak\n",
                  median, p99, differences.back());
      EXPECT_LT(median, 1e-4);
      EXPECT_LT(p99, 1e-2);
    }
    EXPECT_EQ(cmc_states_table(r).labels.size(), 1 + 2 * m.num_coordinates() + 2 * m.muscles.size());
    EXPECT_NE(cmc_average_residuals_text(r).find("pelvis_tx_reserve average"), std::string::npos);
  }
}

// A constraints file's min_nodes and max_nodes, read as OpenSim's ControlLinear reads them: linear
// between nodes and, with extrapolate, past the ends; with steps, the next node's value; without
// nodes, default_min and default_max.
TEST(ControlBounds, FollowTheirNodesAsOpenSimsControlLinear) {
  const std::string dir = refdata::temp_dir("control_bounds");
  const std::string path = dir + "/constraints.xml";
  auto node = [](double t, double v) { return "<ControlLinearNode><t>" + std::to_string(t) + "</t><value>" + std::to_string(v) + "</value></ControlLinearNode>"; };
  std::ofstream(path) << "<OpenSimDocument Version=\"30000\"><ControlSet><objects>"
                         "<ControlLinear name=\"assist.excitation\"><use_steps>false</use_steps><default_min>-3</default_min><default_max>3</default_max>"
                         "<min_nodes>" + node(1, 0) + node(2, 1) + node(3, 1) + "</min_nodes>"
                         "<max_nodes>" + node(1, 2) + node(2, 4) + "</max_nodes></ControlLinear>"
                         "<ControlLinear name=\"stepped.excitation\"><use_steps>true</use_steps>"
                         "<min_nodes>" + node(1, 0.1) + node(2, 0.2) + "</min_nodes><max_nodes>" + node(1, 0.5) + node(2, 0.6) + "</max_nodes></ControlLinear>"
                         "<ControlLinear name=\"plain.excitation\"><default_min>0.02</default_min><default_max>0.9</default_max></ControlLinear>"
                         "</objects></ControlSet></OpenSimDocument>";
  const ControlSetSpec c = read_control_set(path);
  const ControlBounds* a = c.find("assist");
  ASSERT_NE(a, nullptr);
  EXPECT_DOUBLE_EQ(a->min_at(1.5), 0.5);
  EXPECT_DOUBLE_EQ(a->min_at(2.5), 1.0);
  EXPECT_DOUBLE_EQ(a->min_at(0.5), -0.5);  // extrapolated along the first segment
  EXPECT_DOUBLE_EQ(a->max_at(1.25), 2.5);
  EXPECT_DOUBLE_EQ(a->max_at(2.5), 5.0);   // and past the last
  const ControlBounds* s = c.find("stepped");
  ASSERT_NE(s, nullptr);
  EXPECT_DOUBLE_EQ(s->min_at(1.0), 0.1);   // at a node, its value
  EXPECT_DOUBLE_EQ(s->min_at(1.2), 0.2);   // between, the next one's
  EXPECT_DOUBLE_EQ(s->min_at(0.5), 0.1);   // steps do not extrapolate
  EXPECT_DOUBLE_EQ(s->max_at(9.0), 0.6);
  const ControlBounds* p = c.find("plain");
  ASSERT_NE(p, nullptr);
  EXPECT_DOUBLE_EQ(p->min_at(7.0), 0.02);
  EXPECT_DOUBLE_EQ(p->max_at(7.0), 0.9);
}

TEST(ComputedMuscleControl, RefusesTooLittleDataAndUnknownTasks) {
  const Model& m = walker();
  WalkerCmc in = walker_cmc_inputs();
  const ResolvedActuators actuators(m, in.specs);
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(1.19, 1.2);  // less than two windows before the data end
  EXPECT_THROW(computed_muscle_control(m, in.kinematics, nullptr, nullptr, actuators, in.tasks, nullptr, o), InputError);
  in.tasks[0].coordinate = "no_such_coordinate";
  in.tasks[0].file = "tasks.xml";
  in.tasks[0].line = 7;
  try {
    computed_muscle_control(m, in.kinematics, nullptr, nullptr, actuators, in.tasks, nullptr, {});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("tasks.xml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("no_such_coordinate"), std::string::npos);
  }
}

// The Forward tool run on CMC's own controls and states replays CMC's simulation: the same model,
// the same control interpolation (OpenSim's ControlLinear nodes), only the integrator's steps differ.
TEST(ForwardSimulation, ReplaysCmcFromItsControlsAndStates) {
  const Model& m = walker();
  const WalkerCmc in = walker_cmc_inputs();
  const ResolvedActuators actuators(m, in.specs);
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(0.1, 0.5);
  const auto cmc = computed_muscle_control(m, in.kinematics, nullptr, nullptr, actuators, in.tasks, nullptr, o);
  std::vector<std::string> missing;
  const ControlHistory controls = control_history_from_table(m, actuators, cmc_controls_table(cmc), &missing);
  EXPECT_TRUE(missing.empty());
  const Eigen::VectorXd x0 = initial_state_from_table(m, cmc_states_table(cmc), 0.2, true);
  ForwardSimulationOptions fo;
  fo.t0_s = 0.2;
  fo.t1_s = 0.3;
  const auto fwd = forward_simulation(m, actuators, nullptr, nullptr, controls, x0, fo);
  EXPECT_TRUE(fwd.warnings.empty());
  const int i_cmc = static_cast<int>(std::lround((0.3 - cmc.time_s.front()) / 0.001));
  ASSERT_NEAR(cmc.time_s[i_cmc], 0.3, 1e-9);
  ASSERT_NEAR(fwd.time_s.back(), 0.3, 1e-9);
  for (int c = 0; c < m.num_coordinates(); ++c)
    EXPECT_NEAR(fwd.q.bottomRows(1)(0, c), cmc.q(i_cmc, c), 0.1 * M_PI / 180) << m.coordinates[c].name;
  // Without the muscles' excitations (all at their minimum) the same start goes elsewhere.
  ControlHistory limp = controls;
  limp.values.leftCols(m.muscles.size()).setConstant(0.01);
  const auto off = forward_simulation(m, actuators, nullptr, nullptr, limp, x0, fo);
  EXPECT_GT((off.q.bottomRows(1).transpose() - cmc.q.row(i_cmc).transpose()).cwiseAbs().maxCoeff(), 1.0 * M_PI / 180);
}
