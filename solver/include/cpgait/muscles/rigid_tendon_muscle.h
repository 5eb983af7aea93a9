#pragma once
// OpenSim's RigidTendonMuscle: an inextensible tendon, curves given as functions in the document
// (OpenSim's defaults where absent), and no activation dynamics: its activation is its control.
#include "cpgait/capture/function.h"
#include "cpgait/model/model.h"
#include "cpgait/muscles/fiber_state.h"

namespace cpgait::rigid_tendon_muscle {

struct Curves {
  Function active_force_length, passive_force_length, force_velocity;  // against normalised length, velocity
};

Curves default_curves();

// Fibre length (m) and forces along the tendon (N) at path length L (m) and lengthening speed V
// (m/s); the fibre moves at the path's speed (OpenSim's calcFiberVelocityInfo).
double fiber_length(const Muscle& m, double path_length_m);
RigidTendonForces forces(const Muscle& m, double activation, double path_length_m, double path_speed_m_s);

}  // namespace cpgait::rigid_tendon_muscle
