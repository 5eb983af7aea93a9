#pragma once
// The model's passive forces that act on coordinates directly (OpenSim's CoordinateLimitForce),
// as functions of the coordinates and their speeds.
#include "cpgait/model/model.h"

namespace cpgait {

// The generalized force (N m or N) of one CoordinateLimitForce at coordinate value q and speed qd.
double coordinate_limit_force(const CoordinateLimitForce& f, double q, double qd);

// Adds every passive generalized force of the model to tau (nq values).
void add_passive_generalized_forces(const Model& model, const double* q, const double* qd, double* tau);

}  // namespace cpgait
