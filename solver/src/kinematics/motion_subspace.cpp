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

void motion_subspace_and_rate(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                              MotionSubspace& S, std::vector<Eigen::Matrix<double, 6, 1>>& body_velocity,
                              Eigen::Matrix<double, 6, Eigen::Dynamic>& S_rate) {
  using V3 = Eigen::Vector3d;
  S.columns.setZero();
  S_rate.setZero();
  auto& V = body_velocity;
  V[0].setZero();
  for (const Joint& j : model.joints) {
    const V3 w_P = V[j.parent_body].head<3>(), v_P = V[j.parent_body].tail<3>();
    const auto& P = ws.body_in_ground[j.parent_body];
    const Eigen::Matrix3d R_GF = P.rotation * j.parent_offset.rotation;
    const V3 p_GF = P.rotation * j.parent_offset.translation_m + P.translation_m;
    // Column c as a spatial vector (w, v) and its rate: the parent's motion turns it (the motion
    // cross product V_P x S_c), and the joint's own coordinates move it within the parent (dw, dv).
    auto add = [&](int c, const V3& w, const V3& v, const V3& dw, const V3& dv) {
      S.columns.col(c).head<3>() += w;
      S.columns.col(c).tail<3>() += v;
      S_rate.col(c).head<3>() += w_P.cross(w) + dw;
      S_rate.col(c).tail<3>() += w_P.cross(v) + v_P.cross(w) + dv;
    };
    // The child frame's origin M (ground) and its rate within the parent, from the translations.
    V3 translation_F = V3::Zero(), translation_rate_F = V3::Zero();
    for (int s = 3; s < 6; ++s) {
      const TransformAxis& ax = j.axes[s];
      translation_F += ax.axis * axis_value(ax, q);
      if (ax.coordinate >= 0) translation_rate_F += ax.axis * (ax.function.derivative(q[ax.coordinate]) * qd[ax.coordinate]);
    }
    const V3 origin_M_G = R_GF * translation_F + p_GF, origin_rate_G = R_GF * translation_rate_F;
    // Rotation s turns about its axis in the frame left by rotations 1..s-1, which turns within the
    // parent at the angular velocity those rotations give (own_w).
    Eigen::Matrix3d R_partial = Eigen::Matrix3d::Identity();
    V3 own_w = V3::Zero();
    int last_turn = -1;  // the last rotation that turns the frame: none after it needs R_partial
    for (int s = 0; s < 3; ++s)
      if (j.axes[s].coordinate >= 0 || j.axes[s].function.value(0.0) != 0.0) last_turn = s;
    for (int s = 0; s < 3; ++s) {
      const TransformAxis& ax = j.axes[s];
      if (ax.coordinate >= 0) {
        const int c = ax.coordinate;
        const V3 axis_G = R_GF * (R_partial * ax.axis);
        const V3 w = axis_G * ax.function.derivative(q[c]);
        const V3 dw = own_w.cross(w) + axis_G * (ax.function.second_derivative(q[c]) * qd[c]);
        // Rotating about an axis through M's origin: the ground-origin point moves with -w x o_M.
        add(c, w, -w.cross(origin_M_G), dw, -dw.cross(origin_M_G) - w.cross(origin_rate_G));
        own_w += w * qd[c];
      }
      if (s < last_turn && (ax.coordinate >= 0 || ax.function.value(0.0) != 0.0))
        R_partial = (R_partial * axis_rotation(ax.axis, axis_value(ax, q))).eval();
    }
    for (int s = 3; s < 6; ++s) {
      const TransformAxis& ax = j.axes[s];
      if (ax.coordinate < 0) continue;
      const int c = ax.coordinate;
      const V3 axis_G = R_GF * ax.axis;
      add(c, V3::Zero(), axis_G * ax.function.derivative(q[c]), V3::Zero(), axis_G * (ax.function.second_derivative(q[c]) * qd[c]));
    }
    V[j.child_body] = V[j.parent_body];
    for (int c : j.coordinates) V[j.child_body] += S.columns.col(c) * qd[c];
  }
}

}  // namespace cpgait
