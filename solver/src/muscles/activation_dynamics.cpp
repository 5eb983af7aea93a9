#include "cpgait/muscles/activation_dynamics.h"

#include <algorithm>
#include <cmath>

#include "cpgait/muscles/degroote_fregly2016.h"
#include "cpgait/muscles/millard2012.h"
#include "cpgait/muscles/schutte1993.h"

namespace cpgait {

double thelen_activation_rate(const Muscle& m, double u, double a) {
  if (m.degroote) return degroote_fregly2016::activation_rate(m, u, a);
  u = std::clamp(u, m.min_control, m.max_control);
  // A RigidTendonMuscle's activation is its control: the state follows it within a millisecond.
  if (m.rigid_tendon) return (u - a) / 1e-3;
  if (m.schutte) return schutte1993::activation_rate(m, u, a);
  // Millard's activation model is the same equation with the activation held to its range.
  if (m.millard) a = std::clamp(a, m.millard->parameters.minimum_activation, 1.0);
  const double tau = u > a ? m.activation_time_constant_s * (0.5 + 1.5 * a) : m.deactivation_time_constant_s / (0.5 + 1.5 * a);
  return (u - a) / tau;
}

}  // namespace cpgait

namespace cpgait {

double thelen_activation_after(const Muscle& m, double a, double u, double T) {
  const int n = std::max(1, static_cast<int>(std::ceil(T / 1e-3)));
  const double h = T / n;
  for (int i = 0; i < n; ++i) {
    const double k1 = thelen_activation_rate(m, u, a);
    const double k2 = thelen_activation_rate(m, u, a + 0.5 * h * k1);
    const double k3 = thelen_activation_rate(m, u, a + 0.5 * h * k2);
    const double k4 = thelen_activation_rate(m, u, a + h * k3);
    a += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return a;
}

double thelen_excitation_for(const Muscle& m, double a0, double a_target, double T, double lo, double hi) {
  if (thelen_activation_after(m, a0, lo, T) >= a_target) return lo;
  if (thelen_activation_after(m, a0, hi, T) <= a_target) return hi;
  for (int i = 0; i < 40 && hi - lo > 1e-7; ++i) {
    const double mid = 0.5 * (lo + hi);
    (thelen_activation_after(m, a0, mid, T) < a_target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace cpgait
