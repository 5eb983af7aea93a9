#include "cpgait/dynamics/rosenbrock_w.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

DormandPrinceSummary integrate_ros2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                    double t1, Eigen::VectorXd& x, const RosenbrockOptions& o) {
  DormandPrinceSummary s;
  const long n = x.size();
  const double gamma = 1.0 + 1.0 / std::sqrt(2.0);
  Eigen::VectorXd f0(n), f1(n), k1(n), k2(n), y(n), rhs(n);
  double t = t0;
  double h = std::clamp(o.initial_step_s, o.min_step_s, o.max_step_s);
  if (t1 <= t0) {
    s.last_step_s = h;
    return s;
  }
  bool prepared = false;
  while (t < t1) {
    if (s.accepted_steps + s.rejected_steps >= o.max_steps) {
      s.success = false;
      s.message = "too many integrator steps";
      break;
    }
    bool last = false;
    const double h_unclipped = h;
    if (t + h >= t1 - 1e-12 * std::max(1.0, std::abs(t1))) {
      h = t1 - t;
      last = true;
    }
    if (!prepared) {
      prepare(t, x, f0);
      ++s.evaluations;
      prepared = true;
    }
    solve(gamma * h, f0, k1);
    y = x + h * k1;
    f(t + h, y, f1);
    ++s.evaluations;
    rhs = f1 - 2.0 * k1;
    solve(gamma * h, rhs, k2);
    // Error: the difference to the first-order solution x + h k1.
    double norm = 0;
    for (long i = 0; i < n; ++i) {
      const double x_new = x[i] + 1.5 * h * k1[i] + 0.5 * h * k2[i];
      const double e = 0.5 * h * (k1[i] + k2[i]);
      const double scale = o.absolute_tolerance + o.relative_tolerance * std::max(std::abs(x[i]), std::abs(x_new));
      norm += (e / scale) * (e / scale);
    }
    norm = std::sqrt(norm / std::max<long>(1, n));
    if (!std::isfinite(norm)) norm = 1e10;
    const double factor = std::clamp(0.9 / std::sqrt(std::max(norm, 1e-10)), 0.2, 5.0);
    if (norm <= 1.0) {
      ++s.accepted_steps;
      x += 1.5 * h * k1 + 0.5 * h * k2;
      t = last ? t1 : t + h;
      prepared = false;
      if (!last) h = std::min(h * factor, o.max_step_s);
      else s.last_step_s = std::min(std::max(h * factor, h_unclipped), o.max_step_s);  // not the clipped step
    } else {
      ++s.rejected_steps;
      h *= factor;
      if (h < o.min_step_s) {
        s.success = false;
        s.message = "the step size fell below the minimum (" + std::to_string(o.min_step_s) + " s) at t = " + std::to_string(t) + " s";
        break;
      }
    }
  }
  if (s.last_step_s == 0) s.last_step_s = h;
  return s;
}

}  // namespace cpgait
