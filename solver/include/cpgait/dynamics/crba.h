#pragma once
// Composite-rigid-body algorithm: the joint-space mass matrix M(q), with the same ground-frame
// spatial quantities as rnea (each coordinate's motion subspace S_c at the ground origin). For
// coordinates i and j with j's joint an ancestor of (or the same as) i's,
//   M_ij = S_i^T I^c S_j,  I^c = spatial inertia of the subtree below i's joint.
#include <Eigen/Core>
#include <vector>

#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// A body's spatial inertia in ground at the ground origin (rows: moment, force; columns: angular,
// linear velocity), from its pose.
Matrix6d spatial_inertia_in_ground(const Body& body, const PoseT<double>& pose);

// ws and S from forward_kinematics / motion_subspace at q. M is num_coordinates square. composite:
// scratch for the subtrees' inertias (a workspace's, so that evaluations do not allocate).
void crba(const Model& model, const KinematicsWorkspace<double>& ws, const MotionSubspace& S, Eigen::MatrixXd& M,
          std::vector<Matrix6d>& composite);

}  // namespace cpgait
