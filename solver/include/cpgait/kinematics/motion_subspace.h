#pragma once
// Each coordinate's motion subspace in ground: the spatial velocity (angular; linear velocity of the
// point at the ground origin) that a unit rate of that coordinate gives its joint's child, with the
// joint's coupled functions (knee translations, ...) differentiated through. A point p fixed on a
// descendant body moves with dp/dq_c = omega_c x p + v_c. Evaluated on a Jet whose dual part is
// qdot, it also gives dS/dt exactly, which inverse dynamics needs (motion_subspace_and_rate gets
// both faster). The IK Jacobian and the dynamics share it.
#include <ceres/jet.h>

#include <Eigen/Core>
#include <vector>

#include "cpgait/kinematics/forward_kinematics.h"

namespace cpgait {

template <typename T>
struct MotionSubspaceT {
  Eigen::Matrix<T, 6, Eigen::Dynamic> columns;  // rows 0-2 omega_G, rows 3-5 v_G at ground origin
  explicit MotionSubspaceT(const Model& m) : columns(6, m.num_coordinates()) {}
};
using MotionSubspace = MotionSubspaceT<double>;

// dp/dq_c = omega_c x p + v_c for a point p (ground frame) fixed on a body that coordinate c moves.
inline Eigen::Vector3d point_velocity_column(const MotionSubspace& S, int c, const Eigen::Vector3d& p) {
  return S.columns.col(c).head<3>().cross(p) + S.columns.col(c).tail<3>();
}

// One joint's share of the motion subspace: add(c, w, v) receives, for each coordinate c its axes
// move, the angular (w) and ground-origin linear (v) velocity per unit rate of c, given the pose of
// its parent frame F in ground (R_GF, p_GF).
// Inlined: as a call it cost motion_subspace on doubles (every IK iteration, every dynamics
// evaluation) 7 % more instructions (callgrind).
template <typename T, typename Add>
[[gnu::always_inline]] inline void joint_motion_subspace(const Joint& j, const Eigen::Matrix<T, 3, 3>& R_GF, const Eigen::Matrix<T, 3, 1>& p_GF, const T* q,
                           Add&& add) {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using V3 = Eigen::Matrix<T, 3, 1>;
  V3 translation_F = V3::Zero();
  for (int s = 3; s < 6; ++s) translation_F += j.axes[s].axis.cast<T>() * axis_value(j.axes[s], q);
  const V3 origin_M_G = R_GF * translation_F + p_GF;
  // Rotation s turns about its axis expressed in the frame left by rotations 1..s-1.
  M3 R_partial = M3::Identity();
  for (int s = 0; s < 3; ++s) {
    const TransformAxis& ax = j.axes[s];
    if (ax.coordinate >= 0) {
      const V3 w = R_GF * (R_partial * ax.axis.cast<T>()) * ax.function.derivative(q[ax.coordinate]);
      // Rotating about an axis through M's origin: the ground-origin point moves with -w x o_M.
      add(ax.coordinate, w, V3(-w.cross(origin_M_G)));
    }
    if (ax.coordinate >= 0 || ax.function.value(0.0) != 0.0)
      R_partial = (R_partial * axis_rotation(ax.axis, axis_value(ax, q))).eval();
  }
  for (int s = 3; s < 6; ++s) {
    const TransformAxis& ax = j.axes[s];
    if (ax.coordinate < 0) continue;
    add(ax.coordinate, V3::Zero(), V3(R_GF * ax.axis.cast<T>() * ax.function.derivative(q[ax.coordinate])));
  }
}

// Needs ws from forward_kinematics at the same q.
template <typename T>
void motion_subspace(const Model& model, const T* q, const KinematicsWorkspace<T>& ws, MotionSubspaceT<T>& S) {
  using M3 = Eigen::Matrix<T, 3, 3>;
  using V3 = Eigen::Matrix<T, 3, 1>;
  S.columns.setZero();
  for (const Joint& j : model.joints) {
    const auto& P = ws.body_in_ground[j.parent_body];
    const M3 R_GF = P.rotation * j.parent_offset.rotation.cast<T>();
    const V3 p_GF = P.rotation * j.parent_offset.translation_m.cast<T>() + P.translation_m;
    joint_motion_subspace<T>(j, R_GF, p_GF, q, [&](int c, const V3& w, const V3& v) {
      S.columns.col(c).template head<3>() += w;
      S.columns.col(c).template tail<3>() += v;
    });
  }
}

// S and dS/dt at (q, qd) in one pass in doubles, from the pose at q (forward_kinematics): each column
// moves with its joint's parent, whose spatial velocity V_P turns it (V_P x S_c, the motion cross
// product), and with the joint's own coordinates (the rotations before its axis turning it, its
// functions' second derivatives). Equal to motion_subspace on a Jet carrying qd (to rounding), at a
// fraction of its cost. body_velocity (one per body) receives each body's spatial velocity on the way.
void motion_subspace_and_rate(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                              MotionSubspace& S, std::vector<Eigen::Matrix<double, 6, 1>>& body_velocity,
                              Eigen::Matrix<double, 6, Eigen::Dynamic>& S_rate);

// Coordinates that move `body`, root first.
std::vector<int> ancestor_coordinates(const Model& model, int body);

}  // namespace cpgait
