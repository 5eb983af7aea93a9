#include "cpgait/dynamics/dormand_prince.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

namespace {
// Butcher tableau of DOPRI5.
constexpr double c2 = 1.0 / 5, c3 = 3.0 / 10, c4 = 4.0 / 5, c5 = 8.0 / 9;
constexpr double a21 = 1.0 / 5;
constexpr double a31 = 3.0 / 40, a32 = 9.0 / 40;
constexpr double a41 = 44.0 / 45, a42 = -56.0 / 15, a43 = 32.0 / 9;
constexpr double a51 = 19372.0 / 6561, a52 = -25360.0 / 2187, a53 = 64448.0 / 6561, a54 = -212.0 / 729;
constexpr double a61 = 9017.0 / 3168, a62 = -355.0 / 33, a63 = 46732.0 / 5247, a64 = 49.0 / 176, a65 = -5103.0 / 18656;
constexpr double a71 = 35.0 / 384, a73 = 500.0 / 1113, a74 = 125.0 / 192, a75 = -2187.0 / 6784, a76 = 11.0 / 84;
// Error coefficients: 5th-order weights minus the embedded 4th-order ones.
constexpr double e1 = 71.0 / 57600, e3 = -71.0 / 16695, e4 = 71.0 / 1920, e5 = -17253.0 / 339200, e6 = 22.0 / 525,
                 e7 = -1.0 / 40;
}  // namespace

DormandPrinceSummary integrate_dormand_prince(const OdeFunction& f, double t0, double t1, Eigen::VectorXd& x,
                                              const DormandPrinceOptions& o) {
  DormandPrinceSummary s;
  const long n = x.size();
  Eigen::VectorXd k1(n), k2(n), k3(n), k4(n), k5(n), k6(n), k7(n), y(n), y_new(n), err(n);
  double t = t0;
  double h = std::clamp(o.initial_step_s, o.min_step_s, o.max_step_s);
  if (t1 <= t0) {
    s.last_step_s = h;
    return s;
  }
  f(t, x, k1);
  ++s.evaluations;
  double err_previous = 1e-4;  // PI controller memory
  while (t < t1) {
    const double h_unclipped = h;
    bool last = false;
    if (!begin_step(t, t1, o.max_steps, h, last, s)) break;
    y = x + h * a21 * k1;
    f(t + c2 * h, y, k2);
    y = x + h * (a31 * k1 + a32 * k2);
    f(t + c3 * h, y, k3);
    y = x + h * (a41 * k1 + a42 * k2 + a43 * k3);
    f(t + c4 * h, y, k4);
    y = x + h * (a51 * k1 + a52 * k2 + a53 * k3 + a54 * k4);
    f(t + c5 * h, y, k5);
    y = x + h * (a61 * k1 + a62 * k2 + a63 * k3 + a64 * k4 + a65 * k5);
    f(t + h, y, k6);
    y_new = x + h * (a71 * k1 + a73 * k3 + a74 * k4 + a75 * k5 + a76 * k6);
    f(t + h, y_new, k7);
    s.evaluations += 6;
    err = h * (e1 * k1 + e3 * k3 + e4 * k4 + e5 * k5 + e6 * k6 + e7 * k7);
    const double norm = scaled_rms_error(err, x, y_new, o.relative_tolerance, o.absolute_tolerance);
    if (norm <= 1.0) {
      t = last ? t1 : t + h;
      x = y_new;
      k1 = k7;  // first same as last
      // PI control (beta = 0.04), factor limited to [0.2, 10].
      double factor = 0.9 * std::pow(norm, -0.17) * std::pow(err_previous, 0.04);
      factor = std::clamp(norm == 0 ? 10.0 : factor, 0.2, 10.0);
      err_previous = std::max(norm, 1e-4);
      next_step_after_accept(h, factor, last, h_unclipped, o.max_step_s, s);
    } else if (!next_step_after_reject(h, std::max(0.2, 0.9 * std::pow(norm, -0.2)), o.min_step_s, t, s)) {
      break;
    }
  }
  if (s.last_step_s == 0) s.last_step_s = h;
  return s;
}

bool begin_step(double t, double t1, long max_steps, double& h, bool& last, DormandPrinceSummary& s) {
  if (s.accepted_steps + s.rejected_steps >= max_steps) {
    s.success = false;
    s.message = "too many integrator steps";
    return false;
  }
  last = t + h >= t1 - 1e-12 * std::max(1.0, std::abs(t1));
  if (last) h = t1 - t;
  return true;
}

double scaled_rms_error(const Eigen::VectorXd& err, const Eigen::VectorXd& x, const Eigen::VectorXd& x_new, double rtol,
                        double atol) {
  double norm = 0;
  for (Eigen::Index i = 0; i < err.size(); ++i) {
    const double scale = atol + rtol * std::max(std::abs(x[i]), std::abs(x_new[i]));
    norm += (err[i] / scale) * (err[i] / scale);
  }
  norm = std::sqrt(norm / std::max<Eigen::Index>(1, err.size()));
  return std::isfinite(norm) ? norm : 1e10;
}

void next_step_after_accept(double& h, double factor, bool last, double h_unclipped, double max_step_s, DormandPrinceSummary& s) {
  ++s.accepted_steps;
  if (!last) h = std::min(h * factor, max_step_s);
  else s.last_step_s = std::min(std::max(h * factor, h_unclipped), max_step_s);
}

bool next_step_after_reject(double& h, double factor, double min_step_s, double t, DormandPrinceSummary& s) {
  ++s.rejected_steps;
  h *= factor;
  if (h >= min_step_s) return true;
  s.success = false;
  s.message = "the step size fell below the minimum (" + std::to_string(min_step_s) + " s) at t = " + std::to_string(t) + " s";
  return false;
}

}  // namespace cpgait
