#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

std::vector<int> ancestor_coordinates(const Model& model, int body) {
  std::vector<int> out;
  while (body > 0) {
    const Joint& j = model.joints[model.bodies[body].joint];
    out.insert(out.begin(), j.coordinates.begin(), j.coordinates.end());
    body = j.parent_body;
  }
  return out;
}

namespace {

// Whether the joint's columns are fixed in its parent frame: one axis moved by a coordinate, through
// a linear function (a pin or a slider), and no other coordinate among the joint's axes. Then only
// the parent's motion turns them, and no Jet is needed.
bool moves_with_parent_only(const Joint& j) {
  int driven = 0;
  for (const TransformAxis& ax : j.axes)
    if (ax.coordinate >= 0) {
      if (ax.function.kind() != Function::Kind::kLinear && !ax.function.is_constant()) return false;
      ++driven;
    }
  return driven <= 1 && j.coordinates.size() <= 1;
}

}  // namespace

void motion_subspace_rate(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                          const MotionSubspace& S, std::vector<ceres::Jet<double, 1>>& q_jet,
                          std::vector<Eigen::Matrix<double, 6, 1>>& body_velocity, Eigen::Matrix<double, 6, Eigen::Dynamic>& S_rate) {
  using Jet = ceres::Jet<double, 1>;
  using M3 = Eigen::Matrix<Jet, 3, 3>;
  using V3 = Eigen::Matrix<Jet, 3, 1>;
  const int nq = model.num_coordinates();
  for (int c = 0; c < nq; ++c) {
    q_jet[c].a = q[c];
    q_jet[c].v[0] = qd[c];
  }
  S_rate.setZero();
  // Spatial velocity of each body (angular; linear of the point at the ground origin), root first.
  auto& V = body_velocity;
  V[0].setZero();
  for (const Joint& j : model.joints) {
    const Eigen::Vector3d w_P = V[j.parent_body].head<3>(), v_P = V[j.parent_body].tail<3>();
    if (moves_with_parent_only(j)) {
      for (int c : j.coordinates) {
        const Eigen::Vector3d w = S.columns.col(c).head<3>(), v = S.columns.col(c).tail<3>();
        S_rate.col(c).head<3>() += w_P.cross(w);
        S_rate.col(c).tail<3>() += w_P.cross(v) + v_P.cross(w);
      }
    } else {
      const auto& P = ws.body_in_ground[j.parent_body];
      // The parent frame's pose held (no derivative): only the joint's own functions vary here.
      const M3 R_GF = (P.rotation * j.parent_offset.rotation).cast<Jet>();
      const V3 p_GF = (P.rotation * j.parent_offset.translation_m + P.translation_m).cast<Jet>();
      joint_motion_subspace<Jet>(j, R_GF, p_GF, q_jet.data(), [&](int c, const V3& w, const V3& v) {
        const Eigen::Vector3d w_a(w[0].a, w[1].a, w[2].a), v_a(v[0].a, v[1].a, v[2].a);
        S_rate.col(c).head<3>() += w_P.cross(w_a) + Eigen::Vector3d(w[0].v[0], w[1].v[0], w[2].v[0]);
        S_rate.col(c).tail<3>() += w_P.cross(v_a) + v_P.cross(w_a) + Eigen::Vector3d(v[0].v[0], v[1].v[0], v[2].v[0]);
      });
    }
    V[j.child_body] = V[j.parent_body];
    for (int c : j.coordinates) V[j.child_body] += S.columns.col(c) * qd[c];
  }
}

}  // namespace cpgait
