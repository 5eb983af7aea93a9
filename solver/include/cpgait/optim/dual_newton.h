#pragma once
// min sum_i |x_i|^p  subject to  A x = b,  lo <= x <= hi   (p > 1)
// by Newton's method on the Lagrangian dual. The objective is separable, so for multipliers lambda
// each x_i is the clamped minimiser of |x|^p - (A^T lambda)_i x in closed form; the dual is concave
// and its gradient is b - A x(lambda), its (generalized) Hessian -A D A^T with D the curvature of
// the unclamped x_i. Each step solves one m x m system (m = rows of A), so with few equalities and
// many variables (static optimization: 23 coordinates, ~100 actuators) it converges in a handful of
// exact steps and meets the equalities to rounding.
#include <Eigen/Core>

namespace cpgait {

struct DualNewtonOptions {
  double exponent = 2.0;
  double tolerance = 1e-10;   // on |A x - b|_inf, relative to 1 + |b|_inf
  int max_iterations = 200;
};

struct DualNewtonSummary {
  int iterations = 0;
  double equality_residual = 0;  // |A x - b|_inf at the end
  bool converged = false;
};

// lambda: warm start in (empty: cold start), multipliers out (size rows of A). x: solution out.
DualNewtonSummary minimize_power_sum(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo,
                                     const Eigen::VectorXd& hi, const DualNewtonOptions& options, Eigen::VectorXd& lambda,
                                     Eigen::VectorXd& x);

}  // namespace cpgait
