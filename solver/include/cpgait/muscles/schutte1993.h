#pragma once
// OpenSim's deprecated Schutte1993Muscle (Schutte1993Muscle_Deprecated), as old models such as
// BothLegs and the running models use it: curves given as splines in the document (tendon force
// against strain, active and passive force against normalised fibre length) and the iterative
// isometric equilibrium OpenSim computes its fibre length with.
#include "cpgait/capture/function.h"
#include "cpgait/model/model.h"

namespace cpgait::schutte1993 {

struct Curves {
  Function tendon_force_length;   // normalised force against tendon strain
  Function active_force_length;   // against normalised fibre length
  Function passive_force_length;  // against normalised fibre length; unused when exponential_passive
  bool exponential_passive = false;  // the document gives no passive curve: exp(8 (l - 1)) / e^4
  double damping = 0.1;
};

// OpenSim's default curves (Schutte1993Muscle_Deprecated::constructProperties).
Curves default_curves();

// The fibre length (m) at which tendon and fibre forces balance with the fibre at rest, found as
// OpenSim's computeIsometricForce finds it (from the optimal length, secant steps across a sign
// change, stiffness-scaled steps otherwise, to 0.01 N).
double isometric_fiber_length(const Muscle& m, double activation, double path_length_m);

}  // namespace cpgait::schutte1993
