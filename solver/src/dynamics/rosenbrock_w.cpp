#include "cpgait/dynamics/rosenbrock_w.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

DormandPrinceSummary integrate_ros2(const OdeFunction& f, const WPrepare& prepare, const WSolve& solve, double t0,
                                    double t1, Eigen::VectorXd& x, const RosenbrockOptions& o, const WStepDone& step_done) {
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
    const double h_unclipped = h;
    bool last = false;
    if (!begin_step(t, t1, o.max_steps, h, last, s)) break;
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
    y = x + 1.5 * h * k1 + 0.5 * h * k2;
    rhs = 0.5 * h * (k1 + k2);
    const double norm = scaled_rms_error(rhs, x, y, o.relative_tolerance, o.absolute_tolerance);
    const double factor = std::clamp(0.9 / std::sqrt(std::max(norm, 1e-10)), 0.2, 5.0);
    if (norm <= 1.0) {
      const double t_next = last ? t1 : t + h;
      if (step_done) step_done(t, x, t_next, y);
      x = y;
      t = t_next;
      prepared = false;
      next_step_after_accept(h, factor, last, h_unclipped, o.max_step_s, s);
    } else if (!next_step_after_reject(h, factor, o.min_step_s, t, s)) {
      break;
    }
  }
  if (s.last_step_s == 0) s.last_step_s = h;
  return s;
}

}  // namespace cpgait
