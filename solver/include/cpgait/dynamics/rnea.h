#pragma once
// Recursive Newton-Euler inverse dynamics: tau = M(q) qdd + C(q, qd) + G(q) - J^T f_ext.
// Spatial quantities are in ground at the ground origin (Featherstone's fixed-frame form), so the
// knee's spline-coupled translations need no special case: each coordinate's motion subspace S and
// its rate dS/dt come from the coordinate functions (motion_subspace_and_rate).
#include <Eigen/Core>
#include <vector>

#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// A spatial force on a body, in ground: rows 0-2 moment about the ground origin (N m), rows 3-5 force (N).
inline Vector6d spatial_force(const Eigen::Vector3d& force_N, const Eigen::Vector3d& point_G_m,
                              const Eigen::Vector3d& torque_Nm = Eigen::Vector3d::Zero()) {
  Vector6d f;
  f << torque_Nm + point_G_m.cross(force_N), force_N;
  return f;
}

struct DynamicsWorkspace {
  KinematicsWorkspace<double> kinematics;
  MotionSubspace S;
  Eigen::Matrix<double, 6, Eigen::Dynamic> S_rate;  // dS/dt, column per coordinate
  std::vector<Vector6d> velocity, acceleration, force;  // per body
  explicit DynamicsWorkspace(const Model& m)
      : kinematics(m), S(m), S_rate(6, m.num_coordinates()), velocity(m.bodies.size()),
        acceleration(m.bodies.size()), force(m.bodies.size()) {}
};

// external[b]: spatial force applied to body b (empty vector: none). tau has num_coordinates().
void rnea(const Model& model, const double* q, const double* qd, const double* qdd,
          const std::vector<Vector6d>& external, DynamicsWorkspace& ws, double* tau);

// rnea in two parts, for a caller that needs the pose and motion subspace too: the kinematics (pose,
// S, dS/dt and the body velocities), copied out where the caller keeps its own, then the recursion
// on the kinematics already in ws (qd: the speeds rnea_kinematics was given).
void rnea_kinematics(const Model& model, const double* q, const double* qd, DynamicsWorkspace& ws);
void kinematics_values(const DynamicsWorkspace& ws, KinematicsWorkspace<double>& kinematics, MotionSubspace& S);
void rnea_from_kinematics(const Model& model, const double* qd, const double* qdd, const std::vector<Vector6d>& external,
                          DynamicsWorkspace& ws, double* tau);

// tau += J^T f: the generalized forces of spatial forces applied to bodies (wrench[b] on body b, in
// ground at the ground origin), by the backward sweep: each joint carries its subtree's sum.
// `wrench` is consumed (each entry becomes its subtree's sum).
void add_generalized_forces_of_wrenches(const Model& model, const MotionSubspace& S, std::vector<Vector6d>& wrench, double* tau);

}  // namespace cpgait
