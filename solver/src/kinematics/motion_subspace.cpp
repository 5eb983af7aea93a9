#include "cpgait/kinematics/motion_subspace.h"

#include <algorithm>

namespace cpgait {

void motion_subspace(const Model& model, const double* q, const KinematicsWorkspace<double>& ws,
                     MotionSubspace& S) {
  S.columns.setZero();
  for (const Joint& j : model.joints) {
    const auto& P = ws.body_in_ground[j.parent_body];
    const Eigen::Matrix3d R_GF = P.rotation * j.parent_offset.rotation;
    const Eigen::Vector3d p_GF = P.rotation * j.parent_offset.translation_m + P.translation_m;
    // Walk the rotation sequence: rotation s turns about its axis expressed in the frame left by
    // rotations 1..s-1.
    Eigen::Matrix3d R_partial = Eigen::Matrix3d::Identity();
    Eigen::Vector3d translation_F = Eigen::Vector3d::Zero();
    for (int s = 3; s < 6; ++s) translation_F += j.axes[s].axis * axis_value(j.axes[s], q);
    const Eigen::Vector3d origin_M_G = R_GF * translation_F + p_GF;
    for (int s = 0; s < 3; ++s) {
      const TransformAxis& ax = j.axes[s];
      if (ax.coordinate >= 0) {
        const Eigen::Vector3d w = R_GF * (R_partial * ax.axis) * ax.function.derivative(q[ax.coordinate]);
        S.columns.col(ax.coordinate).head<3>() += w;
        // Rotating about an axis through M's origin: the ground-origin point moves with -w x o_M.
        S.columns.col(ax.coordinate).tail<3>() += -w.cross(origin_M_G);
      }
      if (ax.coordinate >= 0 || ax.function.value(0.0) != 0.0)
        R_partial = R_partial * axis_rotation(ax.axis, axis_value(ax, q));
    }
    for (int s = 3; s < 6; ++s) {
      const TransformAxis& ax = j.axes[s];
      if (ax.coordinate < 0) continue;
      S.columns.col(ax.coordinate).tail<3>() += R_GF * ax.axis * ax.function.derivative(q[ax.coordinate]);
    }
  }
}

std::vector<int> ancestor_coordinates(const Model& model, int body) {
  std::vector<int> out;
  while (body > 0) {
    const Joint& j = model.joints[model.bodies[body].joint];
    out.insert(out.begin(), j.coordinates.begin(), j.coordinates.end());
    body = j.parent_body;
  }
  return out;
}

}  // namespace cpgait
