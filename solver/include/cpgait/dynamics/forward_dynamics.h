#pragma once
// Forward dynamics of the tree: qdd = M(q)^-1 (tau - C(q, qd) - G(q) + J^T f_ext), with M from the
// composite-rigid-body algorithm and the bias forces from rnea with qdd = 0.
#include <Eigen/Core>
#include <vector>

#include "cpgait/dynamics/crba.h"
#include "cpgait/dynamics/rnea.h"
#include "cpgait/dynamics/tree_cholesky.h"

namespace cpgait {

struct ForwardDynamicsWorkspace {
  KinematicsWorkspace<double> kinematics;
  MotionSubspace S;
  DynamicsWorkspace dynamics;
  Eigen::MatrixXd M;
  Eigen::VectorXd bias, zero;
  TreeCholesky llt;  // M's factor
  std::vector<Matrix6d> composite;  // crba's scratch
  explicit ForwardDynamicsWorkspace(const Model& m)
      : kinematics(m), S(m), dynamics(m), M(m.num_coordinates(), m.num_coordinates()), bias(m.num_coordinates()),
        zero(Eigen::VectorXd::Zero(m.num_coordinates())), llt(coordinate_parents(m)) {}
};

// external: spatial forces per body (empty: none). qdd has num_coordinates().
void forward_dynamics(const Model& model, const double* q, const double* qd, const double* tau,
                      const std::vector<Vector6d>& external, ForwardDynamicsWorkspace& ws, double* qdd);

// Kinetic plus gravitational potential energy (J), for tests and integrator checks.
double mechanical_energy(const Model& model, const double* q, const double* qd, ForwardDynamicsWorkspace& ws);

}  // namespace cpgait
