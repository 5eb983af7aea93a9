#include "cpgait/muscles/activation_dynamics.h"

#include <algorithm>

namespace cpgait {

double thelen_activation_rate(const Muscle& m, double u, double a) {
  u = std::clamp(u, m.min_control, m.max_control);
  const double tau = u > a ? m.activation_time_constant_s * (0.5 + 1.5 * a) : m.deactivation_time_constant_s / (0.5 + 1.5 * a);
  return (u - a) / tau;
}

}  // namespace cpgait
