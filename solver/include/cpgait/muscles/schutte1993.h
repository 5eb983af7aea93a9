#pragma once
// OpenSim's deprecated Schutte1993Muscle (Schutte1993Muscle_Deprecated), as old models such as
// BothLegs and the running models use it: curves given as splines in the document (tendon force
// against strain, active and passive force against normalised fibre length), the iterative
// isometric equilibrium OpenSim computes its fibre length with, Schutte's inverse force-velocity
// relation with damping and its own activation dynamics (computeActuation), and the capacity static
// optimization gives it (ActivationFiberLengthMuscle_Deprecated::calcInextensibleTendonActiveFiberForce).
#include "cpgait/capture/function.h"
#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"

namespace cpgait::schutte1993 {

struct Curves {
  Function tendon_force_length;   // normalised force against tendon strain
  Function active_force_length;   // against normalised fibre length
  Function passive_force_length;  // against normalised fibre length; unused when exponential_passive
  bool exponential_passive = false;  // the document gives no passive curve: exp(8 (l - 1)) / e^4
  double damping = 0.1;        // normalised passive force per normalised fibre velocity
  double time_scale_s = 0.1;   // the unit of time its normalised velocities and rates use
  double activation1 = 7.667, activation2 = 1.459854;  // activation rate constants (per time_scale)
};

// OpenSim's default curves (Schutte1993Muscle_Deprecated::constructProperties).
Curves default_curves();

// The fibre length (m) at which tendon and fibre forces balance with the fibre at rest, and that
// tendon force (N), found as OpenSim's computeIsometricForce finds them (from the optimal length,
// secant steps across a sign change, stiffness-scaled steps otherwise, to 0.01 N).
struct Isometric {
  double fiber_length_m, tendon_force_N;
};
Isometric isometric_equilibrium(const Muscle& m, double activation, double path_length_m);

// Static optimization's force at this activation: the isometric tendon force times the generic
// force-velocity factor at the path's speed V (m/s), as OpenSim's SO takes it for deprecated muscles
// (the passive force included, the tendon compliant).
double inextensible_tendon_active_force(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

// Compliant tendon (OpenSim's computeActuation): tendon force and fibre velocity at fibre length lm.
CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double path_length_m, double fiber_length_m);
double min_fiber_length(const Muscle& m);  // the muscle's width (at least 1 % of the optimal length)

// Rigid tendon (not an OpenSim option for this muscle, which refuses ignore_tendon_compliance): the
// fibre on the path, its curves, the generic force-velocity factor.
double rigid_tendon_fiber_length(const Muscle& m, double path_length_m);
RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

// d(activation)/dt (1/s) at excitation u.
double activation_rate(const Muscle& m, double u, double a);

}  // namespace cpgait::schutte1993
