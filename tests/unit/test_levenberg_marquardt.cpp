// The bounded Levenberg-Marquardt that inverse kinematics runs per frame: it reaches known minima,
// stops on a bound with the projected gradient zero, and says when it ran out of iterations.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "cpgait/optim/levenberg_marquardt.h"

using namespace cpgait;

namespace {
const double kInf = std::numeric_limits<double>::infinity();

// Rosenbrock as least squares: r = (10 (x1 - x0^2), 1 - x0); minimum at (1, 1) with zero cost.
void rosenbrock(const double* x, double* r, double* J) {
  r[0] = 10 * (x[1] - x[0] * x[0]);
  r[1] = 1 - x[0];
  if (J) J[0] = -20 * x[0], J[1] = 10, J[2] = -1, J[3] = 0;
}
}  // namespace

TEST(LevenbergMarquardt, ReachesRosenbrocksMinimum) {
  Eigen::VectorXd x(2);
  x << -1.2, 1.0;
  LevenbergMarquardtWorkspace w;
  const auto s = levenberg_marquardt(rosenbrock, 2, Eigen::Vector2d::Constant(-kInf), Eigen::Vector2d::Constant(kInf), {}, x, w);
  EXPECT_TRUE(s.converged);
  EXPECT_NEAR(x[0], 1.0, 1e-6);
  EXPECT_NEAR(x[1], 1.0, 1e-6);
  EXPECT_LT(s.final_cost, 1e-12);
  EXPECT_GT(s.initial_cost, 1.0);
  EXPECT_LT(s.iterations, 100);
}

TEST(LevenbergMarquardt, StopsOnAnActiveBound) {
  // Rosenbrock with x0 <= 0.5: the constrained minimum has x0 = 0.5, x1 = 0.25.
  Eigen::VectorXd x(2);
  x << -1.2, 1.0;
  LevenbergMarquardtWorkspace w;
  const auto s = levenberg_marquardt(rosenbrock, 2, Eigen::Vector2d(-kInf, -kInf), Eigen::Vector2d(0.5, kInf), {}, x, w);
  EXPECT_TRUE(s.converged);
  EXPECT_DOUBLE_EQ(x[0], 0.5);
  EXPECT_NEAR(x[1], 0.25, 1e-8);
  // At the bound the gradient pushes outward (x0 wants to grow), and is zero along x1 (to what
  // x1's 1e-8 allows: the curvature along x1 is 100).
  double r[2], J[4];
  rosenbrock(x.data(), r, J);
  EXPECT_LT(J[0] * r[0] + J[2] * r[1], 0.0);
  EXPECT_NEAR(J[1] * r[0] + J[3] * r[1], 0.0, 1e-6);
}

TEST(LevenbergMarquardt, StartOutsideTheBoundsIsProjected) {
  Eigen::VectorXd x(2);
  x << 5.0, -5.0;
  LevenbergMarquardtWorkspace w;
  levenberg_marquardt(rosenbrock, 2, Eigen::Vector2d(-2, -2), Eigen::Vector2d(2, 2), {}, x, w);
  EXPECT_NEAR(x[0], 1.0, 1e-6);
  EXPECT_NEAR(x[1], 1.0, 1e-6);
}

TEST(LevenbergMarquardt, ReportsRunningOutOfIterations) {
  Eigen::VectorXd x(2);
  x << -1.2, 1.0;
  LevenbergMarquardtOptions o;
  o.max_iterations = 2;
  LevenbergMarquardtWorkspace w;
  const auto s = levenberg_marquardt(rosenbrock, 2, Eigen::Vector2d::Constant(-kInf), Eigen::Vector2d::Constant(kInf), o, x, w);
  EXPECT_FALSE(s.converged);
  EXPECT_EQ(s.iterations, 2);
  EXPECT_LE(s.final_cost, s.initial_cost);  // it only takes steps that lower the cost
}

// A problem with residuals left at its minimum (an exponential fitted to noisy samples, as marker IK
// leaves marker errors): once the model predicts the next step to change the cost by less than the
// function tolerance, that step is taken without its Jacobian and the solver stops. The result is the
// one a much tighter tolerance gives, to what the tolerance allows.
TEST(LevenbergMarquardt, LastStepIsTakenWithoutItsJacobian) {
  const int m = 20;
  auto model = [&](const double* x, double* r, double* J, int* with_jacobian, int* without) {
    for (int i = 0; i < m; ++i) {
      const double t = 0.1 * i, e = std::exp(x[1] * t);
      r[i] = x[0] * e - (2.0 * std::exp(-1.3 * t) + 0.05 * std::sin(7.0 * i));  // noise: a non-zero minimum
      if (J) J[2 * i] = e, J[2 * i + 1] = x[0] * t * e;
    }
    ++*(J ? with_jacobian : without);
  };
  auto solve = [&](double tolerance, int& with_jacobian, int& without) {
    Eigen::VectorXd x(2);
    x << 1.0, 0.0;
    LevenbergMarquardtOptions o;
    o.function_tolerance = tolerance;
    LevenbergMarquardtWorkspace w;
    const auto s = levenberg_marquardt([&](const double* xs, double* r, double* J) { model(xs, r, J, &with_jacobian, &without); }, m,
                                       Eigen::Vector2d::Constant(-kInf), Eigen::Vector2d::Constant(kInf), o, x, w);
    EXPECT_TRUE(s.converged);
    return x;
  };
  int loose_j = 0, loose_r = 0, tight_j = 0, tight_r = 0;
  const Eigen::VectorXd loose = solve(1e-7, loose_j, loose_r);
  const Eigen::VectorXd tight = solve(1e-15, tight_j, tight_r);
  EXPECT_EQ(loose_r, 1);                // the last step: residuals only
  EXPECT_LT(loose_j, tight_j);          // fewer Jacobians than running to 1e-15
  EXPECT_LT((loose - tight).cwiseAbs().maxCoeff(), 1e-4);
  std::printf("[ info ] exponential fit: %d Jacobians + %d residual-only at 1e-7, %d + %d at 1e-15; |x - x_tight| %.1e\n", loose_j,
              loose_r, tight_j, tight_r, (loose - tight).cwiseAbs().maxCoeff());
}
