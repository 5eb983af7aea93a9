#pragma once
// What the muscle models (thelen2003.h, millard2012.h) report about a fibre, in SI units.

namespace cpgait {

// Rigid tendon: the fibre's active and passive forces along the tendon (N).
struct RigidTendonForces {
  double active_N, passive_N;
};

// Compliant tendon at a given fibre length: the tendon's force and the fibre's velocity.
struct CompliantTendonFiber {
  double force_N;             // tendon force
  double fiber_velocity_m_s;  // d(fibre length)/dt
  double cos_pennation;
};

struct CompliantMuscleState {
  double activation, fiber_length_m, force_N;
};

}  // namespace cpgait
