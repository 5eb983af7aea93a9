#include "cpgait/muscles/schutte1993.h"

#include <cmath>
#include <limits>

namespace cpgait::schutte1993 {
namespace {

Function spline(std::vector<double> x, std::vector<double> y) { return Function::simm_spline(std::move(x), std::move(y)); }

double passive(const Curves& c, double lN) {
  return c.exponential_passive ? std::exp(8.0 * (lN - 1.0)) / std::exp(4.0) : c.passive_force_length.value(lN);
}

// ActivationFiberLengthMuscle_Deprecated::calcPennation.
double pennation(double fiber_length, double optimal_length, double angle_at_optimal) {
  if (fiber_length < std::numeric_limits<double>::epsilon()) return 0.0;
  const double v = optimal_length * std::sin(angle_at_optimal) / fiber_length;
  if (std::isnan(v) || v <= 0.0) return 0.0;
  if (v >= 1.0) return M_PI / 2;
  return std::asin(v);
}

}  // namespace

Curves default_curves() {
  Curves c;
  c.tendon_force_length = spline({-10, -0.002, -0.001, 0, 0.00131, 0.00281, 0.00431, 0.00581, 0.00731, 0.00881, 0.0103, 0.0118, 0.0123,
                                  9.2, 9.201, 9.202, 20},
                                 {0, 0, 0, 0, 0.0108, 0.0257, 0.0435, 0.0652, 0.0915, 0.123, 0.161, 0.208, 0.227, 345, 345, 345, 345});
  c.active_force_length = spline({-5.307692, -4.307692, -1.923077, -0.884615, -0.269231, 0.230769, 0.461538, 0.52725, 0.62875, 0.71875,
                                  0.86125, 1.045, 1.2175, 1.43875, 1.5, 1.615385, 2.0, 2.961538, 3.692308, 5.461538, 9.901902},
                                 {0.012188, 0.021899, 0.036466, 0.052493, 0.075312, 0.114158, 0.157859, 0.226667, 0.636667, 0.856667,
                                  0.95, 0.993333, 0.77, 0.246667, 0.193821, 0.133252, 0.072683, 0.044417, 0.036341, 0.021899, 0.007332});
  c.passive_force_length = spline({-5, 0.998, 0.999, 1, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.601, 1.602, 5},
                                  {0, 0, 0, 0, 0.035, 0.12, 0.26, 0.55, 1.17, 2, 2, 2, 2});
  return c;
}

Isometric isometric_equilibrium(const Muscle& m, double activation, double length) {
  const Curves& c = *m.schutte;
  const double lopt = m.optimal_fiber_length_m, tsl = m.tendon_slack_length_m, F0 = m.max_isometric_force_N;
  const double alpha0 = m.pennation_angle_at_optimal_rad;
  constexpr double kRoundoff = 1e-7;  // OpenSim's ROUNDOFF_ERROR
  if (lopt < kRoundoff) return {0.0, 0.0};
  const double width = lopt * std::sin(alpha0);
  if (tsl < kRoundoff) {
    const double cos_factor = std::cos(std::atan(width / length)), fiber = length / cos_factor;
    const double active = std::max(0.0, c.active_force_length.value(fiber / lopt) * activation);
    return {fiber, (active + passive(c, fiber / lopt)) * F0 * cos_factor};
  }
  if (length < tsl) return {width, 0.0};
  double fiber = lopt;
  double cos_factor = std::cos(pennation(fiber, lopt, alpha0));
  double tendon = length - fiber * cos_factor;
  if (tendon < tsl) {
    tendon = tsl;
    cos_factor = std::cos(std::atan(width / (length - tendon)));
    fiber = (length - tendon) / cos_factor;
    if (fiber < width) fiber = width;
  }
  double old_fiber = std::numeric_limits<double>::quiet_NaN(), error = 0.0, tendon_force = 0.0;
  for (int i = 0; i < 100; ++i) {
    double active = c.active_force_length.value(fiber / lopt) * activation;
    if (active < 0.0) active = 0.0;
    double pas = passive(c, fiber / lopt);
    if (pas < 0.0) pas = 0.0;
    const double fiber_force = (active + pas) * F0 * cos_factor;
    const double strain = tendon / tsl - 1.0;
    tendon_force = strain < 0.0 ? 0.0 : c.tendon_force_length.value(strain) * F0;
    double old_error = error;
    error = tendon_force - fiber_force;
    if (std::abs(error) <= 0.01) break;  // OpenSim's ERROR_LIMIT, newtons
    if (i == 0) old_error = error;
    if ((error < 0) != (old_error < 0)) {
      // Across a sign change: the secant between this length and the last.
      const double percent = std::abs(error) / (std::abs(error) + std::abs(old_error));
      const double previous = old_fiber;
      old_fiber = fiber;
      fiber += percent * (previous - fiber);
    } else {
      // Otherwise a step scaled by the fibre's and tendon's stiffnesses (OpenSim's, with its
      // floor on the tendon's from a 1200 MPa modulus at 32 MPa maximum stress).
      double tendon_stiffness = (strain < 0.0 ? 0.0 : c.tendon_force_length.value(strain)) * F0 / tsl;
      const double min_tendon_stiffness = (active + pas) * 1200.0 * F0 / (32.0 * tsl);
      if (tendon_stiffness < min_tendon_stiffness) tendon_stiffness = min_tendon_stiffness;
      const double fiber_stiffness = F0 / lopt * (c.active_force_length.value(fiber / lopt) + passive(c, fiber / lopt));
      double change = std::abs(error / (fiber_stiffness / cos_factor + tendon_stiffness));
      if (std::abs(change / lopt) > 0.5) change = 0.5 * lopt;
      old_fiber = fiber;
      fiber += error > 0.0 ? change : -change;
    }
    cos_factor = std::cos(pennation(fiber, lopt, alpha0));
    tendon = length - fiber * cos_factor;
    if (tendon < tsl) {
      tendon = tsl;
      cos_factor = std::cos(std::atan(width / (length - tendon)));
      fiber = (length - tendon) / cos_factor;
    }
  }
  return {fiber, tendon_force};
}

namespace {

// ActivationFiberLengthMuscle_Deprecated::evaluateForceLengthVelocityCurve's force-velocity factor;
// v: normalised shortening velocity (positive concentric).
double generic_force_velocity(double shortening_vN) { return 1.8 - 1.8 / (1.0 + std::exp((0.04 - shortening_vN) / 0.18)); }

// Schutte1993Muscle_Deprecated::calcFiberVelocity: the normalised fibre velocity (optimal lengths
// per time_scale) from the inverse force-velocity relation with damping.
double fiber_velocity_normalised(double damping, double a, double active, double velocity_force) {
  constexpr double kv = 0.15, slope_k = 0.13, fmax = 1.4;
  if (velocity_force < -damping) return velocity_force / damping;
  if (velocity_force < a * active) {
    const double c = kv * (velocity_force - a * active) / damping;
    const double b = -kv * (velocity_force / kv + a * active + damping) / damping;
    return (-b - std::sqrt(b * b - 4 * c)) / 2.0;
  }
  const double c = -(slope_k * kv / (damping * (kv + 1))) * (velocity_force - a * active);
  const double b = -(velocity_force / damping - fmax * a * active / damping - slope_k * kv / (kv + 1));
  return (-b + std::sqrt(b * b - 4 * c)) / 2.0;
}

}  // namespace

double inextensible_tendon_active_force(const Muscle& m, double activation, double L, double V) {
  const double vN = -std::cos(m.pennation_angle_at_optimal_rad) * V / (m.max_contraction_velocity * m.optimal_fiber_length_m);
  return isometric_equilibrium(m, activation, L).tendon_force_N * generic_force_velocity(vN);
}

double min_fiber_length(const Muscle& m) {
  return std::max(m.optimal_fiber_length_m * m.sin_pennation_at_optimal, 0.01 * m.optimal_fiber_length_m);
}

double rigid_tendon_fiber_length(const Muscle& m, double L) {
  const double along = std::max(L - m.tendon_slack_length_m, 0.0);
  const double width = m.optimal_fiber_length_m * m.sin_pennation_at_optimal;
  return std::max(std::sqrt(along * along + width * width), min_fiber_length(m));
}

RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double L, double V) {
  const Curves& c = *m.schutte;
  const double lm = rigid_tendon_fiber_length(m, L), lN = lm / m.optimal_fiber_length_m;
  const double cos_pen = std::cos(pennation(lm, m.optimal_fiber_length_m, m.pennation_angle_at_optimal_rad));
  const double vN = -cos_pen * V / (m.max_contraction_velocity * m.optimal_fiber_length_m);
  const double active = std::max(0.0, c.active_force_length.value(lN)) * activation * generic_force_velocity(vN);
  return {m.max_isometric_force_N * active * cos_pen, m.max_isometric_force_N * std::max(0.0, passive(c, lN)) * cos_pen};
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double L, double lm) {
  const Curves& c = *m.schutte;
  const double lopt = m.optimal_fiber_length_m, tsl = m.tendon_slack_length_m;
  lm = std::max(lm, min_fiber_length(m));
  const double lN = lm / lopt;
  const double cos_pen = std::cos(pennation(lN, 1.0, m.pennation_angle_at_optimal_rad));
  const double strain = (L - lm * cos_pen) / tsl - 1.0;
  const double tendon = strain < 0.0 ? 0.0 : c.tendon_force_length.value(strain);
  const double active = std::max(0.0, c.active_force_length.value(lN));
  double vN;  // optimal lengths per time_scale
  if (std::abs(cos_pen) < 1e-7) {
    // Fibres at 90 degrees: still until the tendon pulls, then moving with the path (OpenSim's
    // stiff-tendon estimate; the path speed is not known here, so at rest).
    vN = 0.0;
  } else {
    const double velocity_force = std::max(0.0, tendon / cos_pen - passive(c, lN));
    vN = fiber_velocity_normalised(c.damping, activation, active, velocity_force);
  }
  return {m.max_isometric_force_N * tendon, vN * lopt / c.time_scale_s, cos_pen};
}

double activation_rate(const Muscle& m, double u, double a) {
  const Curves& c = *m.schutte;
  const double rate = u >= a ? (u - a) * (c.activation1 * u + c.activation2) : (u - a) * c.activation2;
  return rate / c.time_scale_s;
}

}  // namespace cpgait::schutte1993
