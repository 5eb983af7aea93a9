#include "cpgait/optim/dual_newton.h"

#include <Eigen/Cholesky>
#include <cmath>

namespace cpgait {
namespace {

struct Primal {
  double p;
  // argmin_x |x|^p - s x: |x|^(p-1) sign(x) p = s.
  double x(double s) const { return std::copysign(std::pow(std::abs(s) / p, 1.0 / (p - 1.0)), s); }
  double dx_ds(double s) const {
    if (p == 2.0) return 0.5;
    const double a = std::max(std::abs(s), 1e-12);
    return std::pow(a / p, (2.0 - p) / (p - 1.0)) / (p * (p - 1.0));
  }
};

// Dual function value and the primal point for multipliers lambda.
double dual_value(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                  const Primal& pr, const Eigen::VectorXd& lambda, Eigen::VectorXd& x, Eigen::VectorXd& s) {
  s.noalias() = A.transpose() * lambda;
  double g = lambda.dot(b);
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    x[i] = std::clamp(pr.x(s[i]), lo[i], hi[i]);
    g += std::pow(std::abs(x[i]), pr.p) - s[i] * x[i];
  }
  return g;
}

}  // namespace

DualNewtonSummary minimize_power_sum(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo,
                                     const Eigen::VectorXd& hi, const DualNewtonOptions& o, Eigen::VectorXd& lambda,
                                     Eigen::VectorXd& x) {
  const Eigen::Index m = A.rows(), n = A.cols();
  const Primal pr{o.exponent};
  x.resize(n);
  if (lambda.size() != m) {
    // Cold start from the optimum without bounds (every variable free; exact for p = 2), which
    // already has most of the active set right; lambda = 0 would put every variable on a bound.
    const double curvature = pr.dx_ds(1.0);
    Eigen::MatrixXd H0 = curvature * A * A.transpose();
    H0.diagonal().array() += 1e-12 * (1.0 + H0.diagonal().cwiseAbs().maxCoeff());
    lambda = H0.ldlt().solve(b);
  }
  Eigen::VectorXd s(n), x_try(n), s_try(n), d(n);
  Eigen::MatrixXd H(m, m), AD(m, n);
  const double scale = 1.0 + b.cwiseAbs().maxCoeff();
  DualNewtonSummary summary;
  double g = dual_value(A, b, lo, hi, pr, lambda, x, s);
  for (summary.iterations = 0; summary.iterations < o.max_iterations; ++summary.iterations) {
    const Eigen::VectorXd grad = b - A * x;
    summary.equality_residual = grad.cwiseAbs().maxCoeff();
    if (summary.equality_residual <= o.tolerance * scale) {
      summary.converged = true;
      break;
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      const double xi = pr.x(s[i]);
      d[i] = (xi > lo[i] && xi < hi[i]) ? pr.dx_ds(s[i]) : 0.0;
    }
    AD = A * d.asDiagonal();
    H.noalias() = AD * A.transpose();
    // A small ridge keeps the step defined when a row has no free variable left (its actuators
    // all at bounds); the line search still guarantees ascent.
    H.diagonal().array() += 1e-12 * (1.0 + H.diagonal().cwiseAbs().maxCoeff());
    const Eigen::VectorXd step = H.ldlt().solve(grad);
    const double slope = grad.dot(step);
    double t = 1.0;
    double g_try = 0;
    for (int k = 0; k < 40; ++k, t *= 0.5) {
      g_try = dual_value(A, b, lo, hi, pr, lambda + t * step, x_try, s_try);
      if (g_try >= g + 1e-4 * t * slope) break;
    }
    lambda += t * step;
    x.swap(x_try);
    s.swap(s_try);
    g = g_try;
  }
  summary.equality_residual = (A * x - b).cwiseAbs().maxCoeff();
  summary.converged = summary.equality_residual <= o.tolerance * scale;
  return summary;
}

}  // namespace cpgait
