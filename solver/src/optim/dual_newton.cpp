#include "cpgait/optim/dual_newton.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <vector>

namespace cpgait {
namespace {

// A with its nonzero rows per column. A muscle crosses a few of the model's coordinates, so the
// products below go over each column's nonzeros where those are few (gait2392: ~4 rows of 23 per
// muscle column; static optimization on subject01 then takes 1.6x fewer instructions).
class ColumnSparse {
 public:
  explicit ColumnSparse(const Eigen::MatrixXd& A) : A_(A) {
    const Eigen::Index m = A.rows(), n = A.cols();
    begin_.reserve(n + 1);
    begin_.push_back(0);
    long pairs = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto first = rows_.size();
      for (Eigen::Index i = 0; i < m; ++i)
        if (A(i, k) != 0.0) rows_.push_back(static_cast<int>(i));
      const long nk = static_cast<long>(rows_.size() - first);
      pairs += nk * (nk + 1) / 2;
      begin_.push_back(static_cast<int>(rows_.size()));
    }
    // The dense products run vectorised at several times a scalar loop's speed.
    sparse_ = 8 * pairs < static_cast<long>(m * m * n);
  }

  // out = A y
  void times(const Eigen::VectorXd& y, Eigen::VectorXd& out) const {
    if (!sparse_) {
      out.noalias() = A_ * y;
      return;
    }
    out.setZero(A_.rows());
    for (Eigen::Index k = 0; k < A_.cols(); ++k)
      for (int j = begin_[k]; j < begin_[k + 1]; ++j) out[rows_[j]] += A_(rows_[j], k) * y[k];
  }

  // out = A^T lambda
  void transpose_times(const Eigen::VectorXd& lambda, Eigen::VectorXd& out) const {
    if (!sparse_) {
      out.noalias() = A_.transpose() * lambda;
      return;
    }
    out.resize(A_.cols());
    for (Eigen::Index k = 0; k < A_.cols(); ++k) {
      double sum = 0;
      for (int j = begin_[k]; j < begin_[k + 1]; ++j) sum += A_(rows_[j], k) * lambda[rows_[j]];
      out[k] = sum;
    }
  }

  // H = A diag(d) A^T (AD: the dense product's scratch).
  void gram(const Eigen::VectorXd& d, Eigen::MatrixXd& AD, Eigen::MatrixXd& H) const {
    if (!sparse_) {
      AD.noalias() = A_ * d.asDiagonal();
      H.noalias() = AD * A_.transpose();
      return;
    }
    H.setZero();
    for (Eigen::Index k = 0; k < A_.cols(); ++k) {
      if (d[k] == 0.0) continue;
      const int* r = rows_.data() + begin_[k];
      const int nk = begin_[k + 1] - begin_[k];
      for (int a = 0; a < nk; ++a) {
        const double w = d[k] * A_(r[a], k);
        for (int b = a; b < nk; ++b) H(r[b], r[a]) += w * A_(r[b], k);  // rows ascend: the lower triangle
      }
    }
    H.triangularView<Eigen::StrictlyUpper>() = H.transpose();
  }

 private:
  const Eigen::MatrixXd& A_;
  std::vector<int> begin_, rows_;  // column k's nonzero rows: rows_[begin_[k] .. begin_[k + 1])
  bool sparse_ = false;
};

// Dual function value and the primal minimiser y(lambda) of the separable quadratic.
double dual_value(const ColumnSparse& A, const Eigen::VectorXd& b, const Eigen::VectorXd& h, const Eigen::VectorXd& g,
                  const Eigen::VectorXd& lo, const Eigen::VectorXd& hi, const Eigen::VectorXd& lambda, Eigen::VectorXd& y,
                  Eigen::VectorXd& s) {
  A.transpose_times(lambda, s);
  double value = lambda.dot(b);
  for (Eigen::Index i = 0; i < y.size(); ++i) {
    y[i] = std::clamp((s[i] - g[i]) / h[i], lo[i], hi[i]);
    value += 0.5 * h[i] * y[i] * y[i] + g[i] * y[i] - s[i] * y[i];
  }
  return value;
}

// The dual's maximiser along a step p from lambda (s = A^T lambda, q = A^T p, slope: its rate at
// t = 0, > 0). Along p the dual is concave and piecewise quadratic: its rate p^T b - q^T y(t) falls
// by q_i^2 / h_i per unit t while variable i is free, and the breakpoints are where variables
// reach or leave their bounds, so walking them in order finds where the rate reaches zero.
// +infinity where it never does. events: scratch, (t, +-1 entering or leaving, variable).
double maximiser_along(const Eigen::VectorXd& s, const Eigen::VectorXd& q, const Eigen::VectorXd& h, const Eigen::VectorXd& g,
                       const Eigen::VectorXd& lo, const Eigen::VectorXd& hi, double slope,
                       std::vector<std::tuple<double, int, int>>& events) {
  events.clear();
  double curvature = 0;  // sum of q_i^2 / h_i over the free variables
  int free = 0;          // how many: none free is exactly no curvature, whatever the sum's rounding
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    if (q[i] == 0.0) continue;
    const double z0 = (s[i] - g[i]) / h[i], rate = q[i] / h[i];
    const double t_lo = (lo[i] - z0) / rate, t_hi = (hi[i] - z0) / rate;
    const double enter = std::min(t_lo, t_hi), leave = std::max(t_lo, t_hi);  // free in between
    if (!(leave > 0) || !(enter < leave)) continue;
    if (enter <= 0) {
      curvature += q[i] * q[i] / h[i];
      ++free;
    } else {
      events.emplace_back(enter, 1, static_cast<int>(i));
    }
    if (std::isfinite(leave)) events.emplace_back(leave, -1, static_cast<int>(i));
  }
  std::sort(events.begin(), events.end());
  double t = 0, rate = slope;
  for (const auto& [at, change, i] : events) {
    if (free > 0 && rate <= curvature * (at - t)) return t + rate / curvature;
    if (free > 0) rate -= curvature * (at - t);
    t = at;
    free += change;
    curvature = free > 0 ? std::max(0.0, curvature + change * q[i] * q[i] / h[i]) : 0.0;
  }
  return free > 0 && curvature > 0 ? t + rate / curvature : std::numeric_limits<double>::infinity();
}

double ridge(const Eigen::MatrixXd& H) { return 1e-12 * (1.0 + H.diagonal().cwiseAbs().maxCoeff()); }

DualNewtonSummary newton_on_the_dual(const Eigen::MatrixXd& A_dense, const Eigen::VectorXd& b, const Eigen::VectorXd& h,
                                     const Eigen::VectorXd& g, const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                     const DualNewtonOptions& o, Eigen::VectorXd& lambda, Eigen::VectorXd& y) {
  const Eigen::Index m = A_dense.rows(), n = A_dense.cols();
  const ColumnSparse A(A_dense);
  y.resize(n);
  Eigen::VectorXd s(n), y_try(n), s_try(n), d(n), Ay(m), q(n);
  std::vector<std::tuple<double, int, int>> events;
  Eigen::MatrixXd H(m, m), AD(m, n);
  if (lambda.size() != m) {
    // Cold start from the optimum without bounds; lambda = 0 would put most variables on a bound.
    A.gram(h.cwiseInverse(), AD, H);
    H.diagonal().array() += ridge(H);
    A.times((g.array() / h.array()).matrix(), Ay);
    lambda = H.ldlt().solve(b + Ay);
  }
  const double scale = 1.0 + b.cwiseAbs().maxCoeff();
  DualNewtonSummary summary;
  double value = dual_value(A, b, h, g, lo, hi, lambda, y, s);
  for (summary.iterations = 0; summary.iterations < o.max_iterations; ++summary.iterations) {
    A.times(y, Ay);
    const Eigen::VectorXd grad = b - Ay;
    summary.equality_residual = grad.cwiseAbs().maxCoeff();
    if (summary.equality_residual <= o.tolerance * scale) break;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double free_y = (s[i] - g[i]) / h[i];
      d[i] = (free_y > lo[i] && free_y < hi[i]) ? 1.0 / h[i] : 0.0;
    }
    A.gram(d, AD, H);
    // A small ridge keeps the step defined when a row has no free variable left (its actuators all
    // at bounds); the line search still guarantees ascent.
    H.diagonal().array() += ridge(H);
    const auto ldlt = H.ldlt();
    Eigen::VectorXd step = ldlt.solve(grad);
    // Armijo on the dual value. Close to the solution the value's change drops below rounding, so
    // there (and only there, to keep the iteration monotone elsewhere) a step that halves the
    // equality residual is accepted too.
    const bool near_solution = summary.equality_residual < 1e-6 * scale;
    // There the step is refined against H's rounding too: on an ill-conditioned H (a CMC window of
    // the walker) the plain solve's step stopped reducing the residual at 3.6e-8 for good.
    if (near_solution)
      for (int r = 0; r < 2; ++r) step += ldlt.solve(grad - H * step);
    const double slope = grad.dot(step);
    double t = 1.0, value_try = value;
    if (o.exact_line_search) {
      A.transpose_times(step, q);
      // Never beyond the full step: where A x = b cannot be met within the bounds the dual rises
      // without end, and a longer step there threw the multipliers out (a walker's CMC window).
      t = maximiser_along(s, q, h, g, lo, hi, slope, events);
      if (!(t > 0 && t < 1.0)) t = 1.0;
    }
    for (int k = 0; k < 50; ++k, t *= 0.5) {
      value_try = dual_value(A, b, h, g, lo, hi, lambda + t * step, y_try, s_try);
      ++summary.line_search_evaluations;
      if (value_try >= value + 1e-4 * t * slope) break;
      if (!near_solution) continue;
      A.times(y_try, Ay);
      if ((b - Ay).cwiseAbs().maxCoeff() <= 0.5 * summary.equality_residual) break;
    }
    lambda += t * step;
    y.swap(y_try);
    s.swap(s_try);
    value = value_try;
  }
  A.times(y, Ay);
  summary.equality_residual = (Ay - b).cwiseAbs().maxCoeff();
  summary.converged = summary.equality_residual <= o.tolerance * scale;
  return summary;
}

}  // namespace

DualNewtonSummary minimize_separable_quadratic(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                                               const Eigen::VectorXd& h, const Eigen::VectorXd& g,
                                               const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                               const DualNewtonOptions& o, Eigen::VectorXd& lambda, Eigen::VectorXd& y) {
  const bool warm = lambda.size() == A.rows();
  DualNewtonSummary summary = newton_on_the_dual(A, b, h, g, lo, hi, o, lambda, y);
  if (summary.converged || !warm) return summary;
  // A warm start can stall at the right active set above the tolerance: multipliers carried far
  // along H's nearly singular directions round A^T lambda worse than the tolerance (a CMC window
  // of the walker: 1.0e-7 for good, where a cold start reaches 3.1e-8 in two steps). Once more, cold.
  const int warm_iterations = summary.iterations, warm_evaluations = summary.line_search_evaluations;
  lambda.resize(0);
  summary = newton_on_the_dual(A, b, h, g, lo, hi, o, lambda, y);
  summary.iterations += warm_iterations;
  summary.line_search_evaluations += warm_evaluations;
  return summary;
}

namespace {
// sum |x + d|^p - |x|^p, each term without the cancellation of two large sums: the Armijo test on
// the difference of sums failed by rounding for small variables next to large ones (measured).
double objective_change(const Eigen::VectorXd& x, const Eigen::VectorXd& d, double p) {
  double change = 0;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double r = d[i] / x[i];
    change += x[i] != 0 && r > -1 ? std::pow(std::abs(x[i]), p) * std::expm1(p * std::log1p(r))
                                  : std::pow(std::abs(x[i] + d[i]), p) - std::pow(std::abs(x[i]), p);
  }
  return change;
}
}  // namespace

DualNewtonSummary minimize_power_sum(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo,
                                     const Eigen::VectorXd& hi, const DualNewtonOptions& o, Eigen::VectorXd& lambda,
                                     Eigen::VectorXd& x) {
  const Eigen::Index n = A.cols();
  const double p = o.exponent;
  if (!(p >= 2.0)) throw std::invalid_argument("minimize_power_sum: the exponent must be at least 2");
  // p = 2 (and the starting point otherwise): sum x^2 is h = 2, g = 0.
  DualNewtonSummary summary = minimize_separable_quadratic(A, b, Eigen::VectorXd::Constant(n, 2.0),
                                                           Eigen::VectorXd::Zero(n), lo, hi, o, lambda, x);
  if (p == 2.0 || !summary.converged) return summary;

  Eigen::VectorXd h(n), g(n), step, step_lambda;
  const double zero = 0.0;
  for (summary.outer_iterations = 0; summary.outer_iterations < o.max_outer_iterations; ++summary.outer_iterations) {
    // Second-order model of |x|^p around x. Its curvature vanishes at zero for p > 2, which would
    // make the step's dual badly conditioned, so it is floored at 1e-6 of the largest; the steps
    // stay feasible descent steps and the fixed point is unchanged.
    for (Eigen::Index i = 0; i < n; ++i) {
      g[i] = p * std::pow(std::abs(x[i]), p - 1.0) * (x[i] < zero ? -1.0 : 1.0);
      h[i] = p * (p - 1.0) * std::pow(std::abs(x[i]), p - 2.0);
    }
    h = h.cwiseMax(1e-6 * std::max(h.maxCoeff(), 1e-300));
    // The step y solves the quadratic model with A y = b - A x (which also removes any drift from
    // the equalities) and the bounds shifted by x.
    step_lambda.resize(0);
    const DualNewtonSummary qp = minimize_separable_quadratic(A, b - A * x, h, g, lo - x, hi - x, o, step_lambda, step);
    summary.iterations += qp.iterations;
    summary.line_search_evaluations += qp.line_search_evaluations;
    // As the step vanishes g = A^T mu on the free variables: the step's multipliers become the
    // problem's.
    lambda = step_lambda;
    // Stationary once every variable's step is negligible next to its value. A test on the model's
    // decrease, a sum dominated by the largest variables, stopped small ones 0.3 % short (measured).
    if ((step.array().abs() <= 1e-9 * (x.array().abs() + 1e-9)).all()) break;
    // Armijo's test, with the rounding of the large variables' equality drift allowed for: near the
    // solution it outweighs the small variables' descent and made every step fail (measured).
    const double rounding = 1e-13 * (1.0 + x.array().abs().pow(p).sum());
    double t = 1.0;
    int halvings = 0;
    for (; halvings < 50 && objective_change(x, t * step, p) > 1e-4 * t * g.dot(step) + rounding; ++halvings) t *= 0.5;
    if (halvings == 50) break;  // no descent left
    x += t * step;
  }
  summary.equality_residual = (A * x - b).cwiseAbs().maxCoeff();
  summary.converged = summary.equality_residual <= o.tolerance * (1.0 + b.cwiseAbs().maxCoeff());
  return summary;
}

}  // namespace cpgait
