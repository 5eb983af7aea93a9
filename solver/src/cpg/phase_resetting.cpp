#include "cpgait/cpg/phase_resetting.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

int PhaseResetting::touchdown(double t_s, bool loaded_r, bool loaded_l, double cycle_s) {
  const bool loaded[2] = {loaded_r, loaded_l};
  int side = -1;
  for (int s = 1; s >= 0; --s) {
    if (!first_ && loaded[s] && !loaded_[s] && t_s - last_s_[s] > o_.refractory_cycles * cycle_s) {
      last_s_[s] = t_s;
      side = s;  // the right's wins when both touch down at once
    }
    loaded_[s] = loaded[s];
  }
  first_ = false;
  return side;
}

void PhaseResetting::reset(int side, double phase) {
  double error = (side == 0 ? o_.phase_r : o_.phase_l) - phase;
  error -= std::round(error);
  debt_ = o_.share * error;
  ++touchdowns_;
}

double PhaseResetting::rate(double dt_s, double cycle_s) {
  if (debt_ == 0) return 1;
  const double change = std::clamp(debt_ * cycle_s / o_.time_s, -o_.max_rate_change, o_.max_rate_change);
  debt_ -= change * dt_s / cycle_s;
  return 1 + change;
}

}  // namespace cpgait
