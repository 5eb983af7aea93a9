#include "cpgait/optim/levenberg_marquardt.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

namespace cpgait {

LevenbergMarquardtSummary levenberg_marquardt(const ResidualFunction& f, int m, const Eigen::VectorXd& lo,
                                              const Eigen::VectorXd& hi, const LevenbergMarquardtOptions& o,
                                              Eigen::VectorXd& x, LevenbergMarquardtWorkspace& w) {
  const Eigen::Index n = x.size();
  w.J.resize(m, n);
  w.r.resize(m);
  w.r_new.resize(m);
  w.J_new.resize(m, n);
  w.H.resize(n, n);
  w.A.resize(n, n);
  x = x.cwiseMax(lo).cwiseMin(hi);
  LevenbergMarquardtSummary s;
  f(x.data(), w.r.data(), w.J.data());
  double cost = 0.5 * w.r.squaredNorm();
  s.initial_cost = cost;
  double radius = o.initial_radius, decrease_factor = 2.0;
  for (int it = 0; it < o.max_iterations; ++it) {
    w.g.noalias() = w.J.transpose() * w.r;
    // Converged when the gradient projected onto the bounds vanishes.
    if (((x - w.g).cwiseMax(lo).cwiseMin(hi) - x).cwiseAbs().maxCoeff() <= o.gradient_tolerance) {
      s.converged = true;
      break;
    }
    w.H.setZero();
    w.H.selfadjointView<Eigen::Lower>().rankUpdate(w.J.transpose());
    // (J^T J + diag(J^T J) / radius) d = -g, the diagonal clamped as Ceres does.
    w.A = w.H;
    for (Eigen::Index j = 0; j < n; ++j) w.A(j, j) += std::clamp(w.H(j, j), 1e-6, 1e32) / radius;
    // A variable on a bound that the gradient pushes outward stays there: it leaves the system, so
    // the others' step does not count on a move the projection would undo.
    w.rhs = -w.g;
    for (Eigen::Index j = 0; j < n; ++j)
      if ((x[j] <= lo[j] && w.g[j] > 0) || (x[j] >= hi[j] && w.g[j] < 0)) {
        w.A.row(j).setZero();
        w.A.col(j).setZero();
        w.A(j, j) = 1.0;
        w.rhs[j] = 0.0;
      }
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(w.A);
    w.d = llt.solve(w.rhs);
    w.x_new = (x + w.d).cwiseMax(lo).cwiseMin(hi);
    w.step = w.x_new - x;
    // The model's decrease for the step (projected): -(g.s + s.H.s / 2). Where even that is below the
    // function tolerance and the step is nearly Gauss-Newton's (the trust region no smaller than at
    // the start), this is the last step: taken if it does not raise the cost, its Jacobian never
    // needed. A shrunk region makes the prediction small for another reason.
    const double predicted = -(w.g.dot(w.step) + 0.5 * w.step.dot(w.H.selfadjointView<Eigen::Lower>() * w.step));
    ++s.iterations;
    if (radius >= o.initial_radius && predicted >= 0 && predicted <= o.function_tolerance * cost) {
      f(w.x_new.data(), w.r_new.data(), nullptr);
      const double last_cost = 0.5 * w.r_new.squaredNorm();
      if (last_cost <= cost) x = w.x_new, cost = last_cost;
      s.converged = true;
      break;
    }
    // The candidate's Jacobian too: most steps are accepted, and it is then the next iteration's.
    f(w.x_new.data(), w.r_new.data(), w.J_new.data());
    const double new_cost = 0.5 * w.r_new.squaredNorm();
    const double actual = cost - new_cost;
    const bool step_small = w.step.norm() <= (x.norm() + o.parameter_tolerance) * o.parameter_tolerance;
    if (predicted > 0 && actual / predicted > 1e-3) {
      const double rho = actual / predicted;
      x = w.x_new;
      w.r.swap(w.r_new);
      w.J.swap(w.J_new);
      const bool small_change = std::abs(actual) <= o.function_tolerance * cost;
      cost = new_cost;
      radius = std::min(1e16, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      decrease_factor = 2.0;
      if (small_change || step_small) {
        s.converged = true;
        break;
      }
    } else {
      if (step_small || std::abs(actual) <= o.function_tolerance * cost) {
        s.converged = true;  // no step can improve on x
        break;
      }
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      if (radius < 1e-32) break;
    }
  }
  s.final_cost = cost;
  return s;
}

}  // namespace cpgait
