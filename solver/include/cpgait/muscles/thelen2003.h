#pragma once
// Thelen (2003) muscle curves as OpenSim's Thelen2003Muscle implements them, with the fixed-width
// (constant thickness) pennation model. Lengths normalised by optimal fibre length, velocities by
// optimal fibre length x max contraction velocity, forces by max isometric force.
#include "cpgait/model/model.h"

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

}  // namespace cpgait::thelen2003
