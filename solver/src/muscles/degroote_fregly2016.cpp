#include "cpgait/muscles/degroote_fregly2016.h"

#include <algorithm>
#include <cmath>

#include "cpgait/muscles/fiber_equilibrium.h"

namespace cpgait::degroote_fregly2016 {
namespace {

// OpenSim's constants (DeGrooteFregly2016Muscle.h).
constexpr double b11 = 0.8150671134243542, b21 = 1.055033428970575, b31 = 0.162384573599574, b41 = 0.063303448465465;
constexpr double b12 = 0.433004984392647, b22 = 0.716775413397760, b32 = -0.029947116970696, b42 = 0.200356847296188;
constexpr double b13 = 0.1, b23 = 1.0, b33 = 0.353553390593274, b43 = 0.0;
constexpr double kPE = 4.0, kMinNormFiberLength = 0.2;
constexpr double c1 = 0.200, c2 = 1.0, c3 = 0.200;
constexpr double d1 = -0.3211346127989808, d2 = -8.149, d3 = -0.374, d4 = 0.8825327733249912;

double gaussian_like(double x, double b1, double b2, double b3, double b4) {
  const double w = b3 + b4 * x;
  return b1 * std::exp(-0.5 * (x - b2) * (x - b2) / (w * w));
}

double width(const Muscle& m) { return m.optimal_fiber_length_m * m.sin_pennation_at_optimal; }

}  // namespace

double active_force_length(const Parameters& p, double lN) {
  const double x = (lN - 1.0) / p.active_force_width_scale + 1.0;
  return gaussian_like(x, b11, b21, b31, b41) + gaussian_like(x, b12, b22, b32, b42) + gaussian_like(x, b13, b23, b33, b43);
}

double force_velocity(double vN) {
  const double t = d2 * vN + d3;
  return d1 * std::log(t + std::sqrt(t * t + 1.0)) + d4;
}

double force_velocity_inverse(double fv) { return (std::sinh((fv - d4) / d1) - d3) / d2; }

double passive_force_length(const Parameters& p, double lN) {
  if (p.ignore_passive_fiber_force) return 0.0;
  const double e0 = p.passive_fiber_strain_at_one_norm_force;
  const double offset = std::exp(kPE * (kMinNormFiberLength - 1.0) / e0);
  return (std::exp(kPE * (lN - 1.0) / e0) - offset) / (std::exp(kPE) - offset);
}

double tendon_force_length(const Parameters& p, double tN) {
  const double kT = std::log((1.0 + c3) / c1) / (1.0 + p.tendon_strain_at_one_norm_force - c2);
  return c1 * std::exp(kT * (tN - c2)) - c3;
}

double activation_rate(const Muscle& m, double u, double a) {
  u = std::clamp(u, m.min_control, m.max_control);
  const double z = 0.5 + 1.5 * a;
  const double f = 0.5 * std::tanh(0.1 * (u - a));
  return (1.0 / (m.activation_time_constant_s * z) * (f + 0.5) + z / m.deactivation_time_constant_s * (0.5 - f)) * (u - a);
}

double rigid_tendon_fiber_length(const Muscle& m, double L) {
  const double along = L - m.tendon_slack_length_m, w = width(m);
  return std::sqrt(along * along + w * w);
}

RigidTendonForces rigid_tendon_forces(const Muscle& m, double a, double L, double V) {
  const Parameters& p = *m.degroote;
  const double lm = rigid_tendon_fiber_length(m, L);
  const double cos_pen = (L - m.tendon_slack_length_m) / lm;
  const double lN = lm / m.optimal_fiber_length_m;
  const double vN = V * cos_pen / (m.optimal_fiber_length_m * m.max_contraction_velocity);
  const double active = a * active_force_length(p, lN) * force_velocity(vN);
  const double passive = passive_force_length(p, lN) + p.fiber_damping * vN;
  return {m.max_isometric_force_N * active * cos_pen, m.max_isometric_force_N * passive * cos_pen};
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double a, double L, double lm) {
  const Parameters& p = *m.degroote;
  const double w = width(m);
  lm = std::max(lm, std::max(w * 1.0001, kMinNormFiberLength * m.optimal_fiber_length_m));
  const double cos_pen = std::sqrt(1.0 - (w / lm) * (w / lm));
  const double lN = lm / m.optimal_fiber_length_m;
  const double fse = tendon_force_length(p, (L - lm * cos_pen) / m.tendon_slack_length_m);
  const double fal = active_force_length(p, lN), fpe = passive_force_length(p, lN);
  const double fibre_needed = fse / cos_pen - fpe;  // a fal fv + damping vN
  double vN;
  if (p.fiber_damping <= 0) {
    vN = force_velocity_inverse(fibre_needed / std::max(a * fal, 1e-6));
  } else {
    // Newton on a fal fv(v) + beta v = needed: the left side rises with v.
    vN = force_velocity_inverse(std::clamp(fibre_needed / std::max(a * fal, 1e-6), 0.0, 1.7));
    for (int it = 0; it < 30; ++it) {
      const double t = d2 * vN + d3;
      const double err = a * fal * force_velocity(vN) + p.fiber_damping * vN - fibre_needed;
      const double slope = a * fal * d1 * d2 / std::sqrt(t * t + 1.0) + p.fiber_damping;
      if (std::abs(err) < 1e-12) break;
      vN -= err / slope;
    }
  }
  return {m.max_isometric_force_N * fse, vN * m.optimal_fiber_length_m * m.max_contraction_velocity, cos_pen};
}

double compliant_equilibrium_fiber_length(const Muscle& m, double a, double L, double V) {
  const Parameters& p = *m.degroote;
  const double w = width(m);
  auto residual = [&](double lm) {  // tendon minus fibre along the tendon, normalised
    const double cos_pen = std::sqrt(1.0 - (w / lm) * (w / lm));
    const double lN = lm / m.optimal_fiber_length_m;
    const double vN = V * cos_pen / (m.optimal_fiber_length_m * m.max_contraction_velocity);
    const double fibre = a * active_force_length(p, lN) * force_velocity(vN) + passive_force_length(p, lN) + p.fiber_damping * vN;
    return tendon_force_length(p, (L - lm * cos_pen) / m.tendon_slack_length_m) - fibre * cos_pen;
  };
  const double lo = std::max(w * 1.0001, kMinNormFiberLength * m.optimal_fiber_length_m);
  const double hi = std::max(rigid_tendon_fiber_length(m, L), lo);
  return falling_root(residual, lo, hi, 1e-12);
}

}  // namespace cpgait::degroote_fregly2016
