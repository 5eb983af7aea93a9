#pragma once
// The one root finder the muscle models' equilibrium fibre lengths share (and CMC's initial
// activations, whose equilibrium force rises with activation).

namespace cpgait {

// The fibre length in [lo, hi] where `residual` (tendon force minus fibre force along the tendon,
// falling as the fibre lengthens) crosses zero, by bisection to `tolerance` (m); lo or hi when it
// does not cross.
template <typename Residual>
double falling_root(const Residual& residual, double lo, double hi, double tolerance) {
  if (residual(lo) <= 0) return lo;
  if (residual(hi) >= 0) return hi;
  for (int i = 0; i < 60 && hi - lo > tolerance; ++i) {
    const double mid = 0.5 * (lo + hi);
    (residual(mid) > 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace cpgait
