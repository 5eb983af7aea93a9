#include "cpgait/muscles/thelen2003.h"

#include <algorithm>
#include <cmath>

namespace cpgait::thelen2003 {
namespace {
constexpr double kMinActivation = 0.01;          // OpenSim's activation_minimum_value
constexpr double kFvExtrapolationThreshold = 0.95;
constexpr double kMaxPennation = 1.4706289056333368;  // acos(0.1), OpenSim's default maximum
}  // namespace

double active_force_length(const Muscle& m, double l) { return std::exp(-(l - 1.0) * (l - 1.0) / m.kshape_active); }

double passive_force_length(const Muscle& m, double l) {
  if (l <= 1.0) return 0.0;
  return (std::exp(m.kshape_passive * (l - 1.0) / m.fmax_muscle_strain) - 1.0) / (std::exp(m.kshape_passive) - 1.0);
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
  double v0, s0, v1, s1;
  const double upper = kFvExtrapolationThreshold * afl * flen;
  thelen_velocity(m, a, afl, 0.0, v0, s0);
  thelen_velocity(m, a, afl, upper, v1, s1);
  double Fm;
  if (v <= v0) {
    Fm = (v - v0) / s0;  // beyond the concentric asymptote: linear extrapolation
  } else if (v <= 0.0) {
    Fm = afl * (k + v) / (k - v / af);  // concentric branch of Eq. 6
  } else if (v < v1) {
    const double c = (2.0 + 2.0 / af) / (flen - 1.0);
    Fm = afl * (k + c * flen * v) / (k + c * v);  // eccentric branch
  } else {
    Fm = upper + (v - v1) / s1;
  }
  return Fm / afl;
}

RigidTendonFiber rigid_tendon_fiber(const Muscle& m, double L, double V) {
  const double height = m.optimal_fiber_length_m * std::sin(m.pennation_angle_at_optimal_rad);
  const double along_tendon = L - m.tendon_slack_length_m;
  // Fixed-width pennation: the fibre is the hypotenuse over the parallelogram's height, never
  // shorter than the length at which pennation reaches its maximum.
  const double min_length = std::max(height / std::sin(kMaxPennation), 0.01 * m.optimal_fiber_length_m);
  const double fiber = std::max(std::sqrt(height * height + along_tendon * along_tendon), min_length);
  const double cos_pen = std::sqrt(std::max(0.0, 1.0 - (height / fiber) * (height / fiber)));
  return {fiber, cos_pen, V * cos_pen};
}

double rigid_tendon_active_force(const Muscle& m, double activation, double L, double V) {
  const RigidTendonFiber f = rigid_tendon_fiber(m, L, V);
  const double a = std::clamp(activation, kMinActivation, 1.0);
  const double lN = f.fiber_length_m / m.optimal_fiber_length_m;
  const double vN = f.fiber_velocity_m_s / (m.optimal_fiber_length_m * m.max_contraction_velocity);
  const double fal = active_force_length(m, lN);
  const double fv = force_velocity_multiplier(m, a, fal, vN);
  return m.max_isometric_force_N * a * fal * fv * f.cos_pennation;
}

double rigid_tendon_passive_force(const Muscle& m, double L) {
  const RigidTendonFiber f = rigid_tendon_fiber(m, L, 0.0);
  return m.max_isometric_force_N * passive_force_length(m, f.fiber_length_m / m.optimal_fiber_length_m) * f.cos_pennation;
}

}  // namespace cpgait::thelen2003
