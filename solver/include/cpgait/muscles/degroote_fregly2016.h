#pragma once
// OpenSim's DeGrooteFregly2016Muscle: De Groote et al. (2016)'s closed-form curves with OpenSim's
// constants (its tendon curve passes through zero at the slack length), its activation dynamics
// (a tanh blend of the activation and deactivation time constants) and fixed-width pennation. The
// compliant tendon is integrated with the fibre length as the state (OpenSim's state is the
// normalised tendon force; the equations are the same).
#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"

namespace cpgait::degroote_fregly2016 {

struct Parameters {
  double active_force_width_scale = 1.0;
  double fiber_damping = 0.0;  // normalised force per normalised velocity
  double passive_fiber_strain_at_one_norm_force = 0.6;
  double tendon_strain_at_one_norm_force = 0.049;
  bool ignore_passive_fiber_force = false;
  bool ignore_tendon_compliance = false;
};

double active_force_length(const Parameters& p, double norm_fiber_length);
double force_velocity(double norm_fiber_velocity);
double force_velocity_inverse(double force_velocity_multiplier);
double passive_force_length(const Parameters& p, double norm_fiber_length);
double tendon_force_length(const Parameters& p, double norm_tendon_length);

// da/dt at excitation u (clamped to the control range) and activation a.
double activation_rate(const Muscle& m, double excitation, double activation);

double rigid_tendon_fiber_length(const Muscle& m, double path_length_m);
RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);
CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double path_length_m, double fiber_length_m);
double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

}  // namespace cpgait::degroote_fregly2016
