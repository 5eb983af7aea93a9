#pragma once
// The model's passive forces as generalized forces: those acting on coordinates directly (OpenSim's
// CoordinateLimitForce, SpringGeneralizedForce and ExpressionBasedCoordinateForce) and path springs
// (OpenSim's PathSpring), as functions of the coordinates and their speeds.
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/model.h"

namespace cpgait {

// The generalized force (N m or N) of one CoordinateLimitForce at coordinate value q and speed qd.
double coordinate_limit_force(const CoordinateLimitForce& f, double q, double qd);

// A PathSpring's tension (N) at a path length (m) and lengthening speed (m/s): OpenSim's
// stiffness * max(0, L - resting) * (1 + dissipation * dL/dt).
double path_spring_tension(const PathSpring& s, double length_m, double lengthening_speed_m_s);

// Adds every passive generalized force of the model to tau (nq values).
void add_passive_generalized_forces(const Model& model, const double* q, const double* qd, double* tau);
// The same with the caller's forward kinematics and motion subspace at q, which path springs need
// (SO and forward dynamics have them already).
void add_passive_generalized_forces(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                                    const MotionSubspace& S, double* tau);

}  // namespace cpgait
