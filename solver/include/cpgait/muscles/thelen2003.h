#pragma once
// Thelen (2003) muscle curves as OpenSim's Thelen2003Muscle implements them, with the fixed-width
// (constant thickness) pennation model. Lengths normalised by optimal fibre length, velocities by
// optimal fibre length x max contraction velocity, forces by max isometric force.
#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"

namespace cpgait::thelen2003 {

double active_force_length(const Muscle& m, double norm_fiber_length);
double passive_force_length(const Muscle& m, double norm_fiber_length);
double tendon_force_strain(const Muscle& m, double norm_tendon_length);
// Normalised fibre velocity for a given activation, active force-length value and active force
// a*fal*fv (Thelen's Eqs. 6-7, extrapolated linearly beyond 0.95 of the eccentric asymptote).
double fiber_velocity(const Muscle& m, double activation, double fal, double active_force);
// The inverse: the force-velocity multiplier fv for a normalised fibre velocity.
double force_velocity_multiplier(const Muscle& m, double activation, double fal, double norm_fiber_velocity);

// Fibre geometry with a rigid tendon: fibre length, cos(pennation), and fibre velocity.
struct RigidTendonFiber {
  double fiber_length_m;
  double cos_pennation;
  double fiber_velocity_m_s;
};
RigidTendonFiber rigid_tendon_fiber(const Muscle& m, double path_length_m, double path_speed_m_s);

// Active fibre force along the tendon (N) for an inextensible tendon, activation clamped to
// [0.01, 1] as OpenSim does: static optimization's "optimal force" of a muscle at a = 1.
double rigid_tendon_active_force(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);
// Passive fibre force along the tendon (N) for an inextensible tendon.
double rigid_tendon_passive_force(const Muscle& m, double path_length_m);
// Both at once (one fibre geometry), for the dynamics' every evaluation.
RigidTendonForces rigid_tendon_forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

// Active fibre force along the tendon (N) at a fibre length and velocity (either tendon model).
double active_fiber_force_along_tendon(const Muscle& m, double activation, double fiber_length_m,
                                       double fiber_velocity_m_s);
double passive_fiber_force_along_tendon(const Muscle& m, double fiber_length_m);
double cos_pennation(const Muscle& m, double fiber_length_m);
double min_fiber_length(const Muscle& m);  // where pennation reaches OpenSim's maximum

// Compliant tendon, as OpenSim's Thelen2003Muscle integrates it: the fibre length is a state. The
// tendon, stretched to L - lm cos(alpha), sets the force; the contractile element carries that
// force (along the fibre) minus the parallel elastic part, and Thelen's inverse force-velocity
// relation turns it into the fibre's velocity.
CompliantTendonFiber compliant_tendon_fiber(const Muscle& m, double activation, double path_length_m,
                                            double fiber_length_m);
// The fibre length at which tendon and fibre forces balance with the fibre moving at its share of
// the path's speed: the initial state of a compliant muscle.
double compliant_equilibrium_fiber_length(const Muscle& m, double activation, double path_length_m,
                                          double path_speed_m_s);

}  // namespace cpgait::thelen2003
