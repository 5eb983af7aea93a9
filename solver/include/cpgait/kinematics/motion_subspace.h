#pragma once
// Each coordinate's motion subspace in ground: the spatial velocity (angular; linear velocity of the
// point at the ground origin) that a unit rate of that coordinate gives its joint's child, with the
// joint's coupled functions (knee translations, ...) differentiated through. A point p fixed on a
// descendant body moves with dp/dq_c = omega_c x p + v_c. Inverse dynamics and the IK Jacobian
// share it.
#include <Eigen/Core>
#include <vector>

#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

struct MotionSubspace {
  Eigen::Matrix<double, 6, Eigen::Dynamic> columns;  // rows 0-2 omega_G, rows 3-5 v_G at ground origin
  explicit MotionSubspace(const Model& m) : columns(6, m.num_coordinates()) {}
};

// Needs ws from forward_kinematics at the same q.
void motion_subspace(const Model& model, const double* q, const KinematicsWorkspace<double>& ws, MotionSubspace& S);

// Coordinates that move `body`, root first.
std::vector<int> ancestor_coordinates(const Model& model, int body);

}  // namespace cpgait
