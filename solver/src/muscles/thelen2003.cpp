#include "cpgait/muscles/thelen2003.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cpgait/muscles/activation_dynamics.h"
#include "cpgait/muscles/fiber_equilibrium.h"

namespace cpgait::thelen2003 {
namespace {
constexpr double kMinActivation = 0.01;          // OpenSim's activation_minimum_value
constexpr double kFvExtrapolationThreshold = 0.95;
// OpenSim's default maximum pennation is acos(0.1); its sine, sqrt(1 - 0.1^2), as a constant (the
// muscle functions run for every muscle in every evaluation: sin() was 8 % of a simulation's time,
// hence also the muscle's own sine kept in the model).
constexpr double kSinMaxPennation = 0.99498743710661995;
// The fibre's constant height (fixed-width pennation) and the shortest fibre length it allows.
double fiber_height(const Muscle& m) { return m.optimal_fiber_length_m * m.sin_pennation_at_optimal; }
double min_fiber_length_for(const Muscle& m, double height) { return std::max(height / kSinMaxPennation, 0.01 * m.optimal_fiber_length_m); }
double cos_pennation_for(const Muscle& m, double height, double lm) {
  const double r = height / std::max(lm, min_fiber_length_for(m, height));
  return std::sqrt(std::max(0.0, 1.0 - r * r));
}
}  // namespace

double active_force_length(const Muscle& m, double l) { return std::exp(-(l - 1.0) * (l - 1.0) / m.kshape_active); }

double passive_force_length(const Muscle& m, double l) {
  if (l <= 1.0) return 0.0;
  // The denominator's exp is the muscle's constant, and muscles share their shape factor (OpenSim's
  // default 4): it is kept while the factor repeats.
  thread_local double k_kept = std::numeric_limits<double>::quiet_NaN(), denominator = 0;
  if (m.kshape_passive != k_kept) {
    k_kept = m.kshape_passive;
    denominator = std::exp(k_kept) - 1.0;
  }
  return (std::exp(m.kshape_passive * (l - 1.0) / m.fmax_muscle_strain) - 1.0) / denominator;
}

double tendon_force_strain(const Muscle& m, double norm_tendon_length) {
  // Toe region to F = 0.33 at strain eToe, then linear; eToe and klin are the exact values of which
  // Thelen's paper prints rounded ones.
  const double x = norm_tendon_length - 1.0, e0 = m.fmax_tendon_strain;
  const double kToe = 3.0, fToe = 0.33, e3 = std::exp(3.0);
  const double eToe = 99.0 * e0 * e3 / (166.0 * e3 - 67.0);
  const double klin = 0.67 / (e0 - eToe);
  if (x > eToe) return klin * (x - eToe) + fToe;
  if (x > 0.0) return fToe / (std::exp(kToe) - 1.0) * (std::exp(kToe * x / eToe) - 1.0);
  return 0.0;
}

namespace {
// dlceN(Fm) on the valid region and its slope, for Fm = a*fal*fv.
void thelen_velocity(const Muscle& m, double a, double afl, double Fm, double& v, double& dv_dF) {
  const double af = m.af, flen = m.flen, k = 0.25 + 0.75 * a;
  double b, db;
  if (Fm <= afl) {
    b = afl + Fm / af;
    db = 1.0 / af;
  } else {
    b = (2.0 + 2.0 / af) * (afl * flen - Fm) / (flen - 1.0);
    db = -(2.0 + 2.0 / af) / (flen - 1.0);
  }
  v = k * (Fm - afl) / b;
  dv_dF = k / b - k * (Fm - afl) / (b * b) * db;
}
}  // namespace

double fiber_velocity(const Muscle& m, double a, double fal, double Fm) {
  const double afl = a * fal, upper = kFvExtrapolationThreshold * afl * m.flen;
  double v, slope;
  if (Fm > 0.0 && Fm < upper) {
    thelen_velocity(m, a, afl, Fm, v, slope);
    return v;
  }
  const double F0 = Fm <= 0.0 ? 0.0 : upper;
  thelen_velocity(m, a, afl, F0, v, slope);
  return v + slope * (Fm - F0);
}

double force_velocity_multiplier(const Muscle& m, double a, double fal, double v) {
  // Closed-form inverse of fiber_velocity (monotonic in Fm), region by region.
  const double afl = a * fal, flen = m.flen, af = m.af, k = 0.25 + 0.75 * a;
  if (afl <= 0) return 1.0;
  // The region boundaries in closed form (thelen_velocity at Fm = 0 and at the extrapolation
  // threshold): this runs for every muscle in every evaluation.
  double Fm;
  if (v <= 0.0) {
    const double v0 = -k, s0 = k / afl * (1.0 + 1.0 / af);
    if (v <= v0) Fm = (v - v0) / s0;                 // beyond the concentric asymptote: linear extrapolation
    else Fm = afl * (k + v) / (k - v / af);           // concentric branch of Eq. 6
  } else {
    const double c = (2.0 + 2.0 / af) / (flen - 1.0);
    const double upper = kFvExtrapolationThreshold * afl * flen;
    const double b1 = c * (afl * flen - upper);
    const double v1 = k * (upper - afl) / b1, s1 = k / b1 + k * (upper - afl) / (b1 * b1) * c;
    if (v < v1) Fm = afl * (k + c * flen * v) / (k + c * v);  // eccentric branch
    else Fm = upper + (v - v1) / s1;
  }
  return Fm / afl;
}

RigidTendonFiber rigid_tendon_fiber(const Muscle& m, double L, double V) {
  const double height = fiber_height(m);
  const double along_tendon = L - m.tendon_slack_length_m;
  // Fixed-width pennation: the fibre is the hypotenuse over the parallelogram's height, never
  // shorter than the length at which pennation reaches its maximum.
  const double fiber = std::max(std::sqrt(height * height + along_tendon * along_tendon), min_fiber_length_for(m, height));
  const double cos_pen = std::sqrt(std::max(0.0, 1.0 - (height / fiber) * (height / fiber)));
  return {fiber, cos_pen, V * cos_pen};
}

double cos_pennation(const Muscle& m, double lm) { return cos_pennation_for(m, fiber_height(m), lm); }

double min_fiber_length(const Muscle& m) { return min_fiber_length_for(m, fiber_height(m)); }

namespace {
// The fibre forces along the tendon with cos(pennation) already known.
double active_along_tendon(const Muscle& m, double activation, double lm, double vm, double cos_pen) {
  const double a = std::clamp(activation, kMinActivation, 1.0);
  const double lN = lm / m.optimal_fiber_length_m;
  const double vN = vm / (m.optimal_fiber_length_m * m.max_contraction_velocity);
  const double fal = active_force_length(m, lN);
  const double fv = force_velocity_multiplier(m, a, fal, vN);
  return m.max_isometric_force_N * a * fal * fv * cos_pen;
}
double passive_along_tendon(const Muscle& m, double lm, double cos_pen) {
  return m.max_isometric_force_N * passive_force_length(m, lm / m.optimal_fiber_length_m) * cos_pen;
}
}  // namespace

double active_fiber_force_along_tendon(const Muscle& m, double activation, double lm, double vm) {
  return active_along_tendon(m, activation, lm, vm, cos_pennation(m, lm));
}

double passive_fiber_force_along_tendon(const Muscle& m, double lm) { return passive_along_tendon(m, lm, cos_pennation(m, lm)); }

double rigid_tendon_active_force(const Muscle& m, double activation, double L, double V) {
  const RigidTendonFiber f = rigid_tendon_fiber(m, L, V);
  return active_along_tendon(m, activation, f.fiber_length_m, f.fiber_velocity_m_s, f.cos_pennation);
}

double rigid_tendon_passive_force(const Muscle& m, double L) {
  const RigidTendonFiber f = rigid_tendon_fiber(m, L, 0.0);
  return passive_along_tendon(m, f.fiber_length_m, f.cos_pennation);
}

RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double L, double V) {
  const RigidTendonFiber f = rigid_tendon_fiber(m, L, V);
  return {active_along_tendon(m, activation, f.fiber_length_m, f.fiber_velocity_m_s, f.cos_pennation),
          passive_along_tendon(m, f.fiber_length_m, f.cos_pennation)};
}

CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double L, double lm) {
  const double height = fiber_height(m);
  lm = std::max(lm, min_fiber_length_for(m, height));
  const double cos_pen = cos_pennation_for(m, height, lm);
  const double tendon = L - lm * cos_pen;
  const double force = m.max_isometric_force_N * tendon_force_strain(m, tendon / m.tendon_slack_length_m);
  const double a = std::clamp(activation, kMinActivation, 1.0);
  const double lN = lm / m.optimal_fiber_length_m;
  const double fal = active_force_length(m, lN);
  const double active = force / (m.max_isometric_force_N * cos_pen) - passive_force_length(m, lN);
  const double vN = fiber_velocity(m, a, fal, active);
  return {force, vN * m.optimal_fiber_length_m * m.max_contraction_velocity, cos_pen};
}

double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double L, double V) {
  // Residual: tendon force minus fibre force (along the tendon); it falls as the fibre lengthens
  // (the tendon slackens while the fibre's passive force grows).
  auto residual = [&](double lm) {
    const double cos_pen = cos_pennation(m, lm);
    const double tendon = m.max_isometric_force_N * tendon_force_strain(m, (L - lm * cos_pen) / m.tendon_slack_length_m);
    return tendon - active_fiber_force_along_tendon(m, activation, lm, V * cos_pen) - passive_fiber_force_along_tendon(m, lm);
  };
  const double lo = min_fiber_length(m);
  const double hi = std::max(rigid_tendon_fiber(m, L, 0.0).fiber_length_m, lo);
  return falling_root(residual, lo, hi, 1e-10);
}

}  // namespace cpgait::thelen2003
