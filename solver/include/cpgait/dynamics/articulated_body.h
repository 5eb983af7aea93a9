#pragma once
// Featherstone's articulated-body algorithm (RBDA, Table 7.1) with every spatial quantity in ground
// at the ground origin, as rnea and crba keep them, so no transform passes between bodies:
// qdd = M^-1 (tau - C - G + J^T f_ext) in O(n) without forming M. For evaluations that need the
// accelerations only (an integrator's stages); where M itself is needed, crba and its factor.
#include <Eigen/Core>
#include <vector>

#include "cpgait/dynamics/crba.h"
#include "cpgait/dynamics/rnea.h"

namespace cpgait {

struct ArticulatedBodyWorkspace {
  std::vector<Matrix6d> inertia;           // per body: its subtree's articulated inertia
  std::vector<Vector6d> bias;              // per body: its subtree's articulated bias force
  std::vector<Vector6d> velocity_product;  // per body: dS/dt qd of its joint
  std::vector<Vector6d> acceleration;      // per body (gravity as the ground accelerating upwards)
  // Per joint, in the leading rows and columns (a joint has at most 6 coordinates): I^A S,
  // (S^T I^A S)^-1 and tau - S^T p^A.
  std::vector<Matrix6d> U, D_inverse;
  std::vector<Vector6d> u;
  explicit ArticulatedBodyWorkspace(const Model& m);
};

// ws from rnea_kinematics at (q, qd) (pose, S, dS/dt, body velocities); tau per coordinate; external:
// spatial forces per body (empty: none). Returns false, qdd untouched, where a joint's
// S^T I^A S is not positive definite (a coordinate without motion at this pose): M is singular there.
bool articulated_body_accelerations(const Model& model, const double* qd, const double* tau,
                                    const std::vector<Vector6d>& external, const DynamicsWorkspace& ws,
                                    ArticulatedBodyWorkspace& aw, double* qdd);

}  // namespace cpgait
