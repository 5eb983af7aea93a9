#include "cpgait/dynamics/rnea.h"

namespace cpgait {

void rnea_kinematics(const Model& model, const double* q, const double* qd, DynamicsWorkspace& ws) {
  const int nq = model.num_coordinates();
  for (int c = 0; c < nq; ++c) {
    ws.q_jet[c].a = q[c];
    ws.q_jet[c].v[0] = qd[c];
  }
  forward_kinematics(model, ws.q_jet.data(), ws.kinematics);
  motion_subspace(model, ws.q_jet.data(), ws.kinematics, ws.S);
}

void kinematics_values(const DynamicsWorkspace& ws, KinematicsWorkspace<double>& kinematics, MotionSubspace& S) {
  for (std::size_t b = 0; b < kinematics.body_in_ground.size(); ++b) {
    const auto& from = ws.kinematics.body_in_ground[b];
    auto& to = kinematics.body_in_ground[b];
    for (int r = 0; r < 3; ++r) {
      to.translation_m[r] = from.translation_m[r].a;
      for (int k = 0; k < 3; ++k) to.rotation(r, k) = from.rotation(r, k).a;
    }
  }
  for (Eigen::Index c = 0; c < S.columns.cols(); ++c)
    for (int r = 0; r < 6; ++r) S.columns(r, c) = ws.S.columns(r, c).a;
}

void rnea(const Model& model, const double* q, const double* qd, const double* qdd,
          const std::vector<Vector6d>& external, DynamicsWorkspace& ws, double* tau) {
  rnea_kinematics(model, q, qd, ws);
  rnea_from_kinematics(model, qd, qdd, external, ws, tau);
}

void rnea_from_kinematics(const Model& model, const double* qd, const double* qdd, const std::vector<Vector6d>& external,
                          DynamicsWorkspace& ws, double* tau) {
  ws.velocity[0].setZero();
  ws.acceleration[0].setZero();
  for (const Joint& j : model.joints) {
    Vector6d V = ws.velocity[j.parent_body], A = ws.acceleration[j.parent_body];
    for (int c : j.coordinates) {
      for (int r = 0; r < 6; ++r) {
        const double s = ws.S.columns(r, c).a, sdot = ws.S.columns(r, c).v[0];
        V[r] += s * qd[c];
        A[r] += s * qdd[c] + sdot * qd[c];
      }
    }
    ws.velocity[j.child_body] = V;
    ws.acceleration[j.child_body] = A;

    // Newton-Euler for the child body about its centre of mass, moved to the ground origin.
    const Body& b = model.bodies[j.child_body];
    const auto& X = ws.kinematics.body_in_ground[j.child_body];
    Eigen::Matrix3d R;
    Eigen::Vector3d p;
    for (int r = 0; r < 3; ++r) {
      p[r] = X.translation_m[r].a;
      for (int k = 0; k < 3; ++k) R(r, k) = X.rotation(r, k).a;
    }
    const Eigen::Vector3d c = R * b.com_m + p;
    const Eigen::Matrix3d I = R * b.inertia_kg_m2 * R.transpose();
    const Eigen::Vector3d w = V.head<3>(), alpha = A.head<3>();
    const Eigen::Vector3d v_com = V.tail<3>() + w.cross(c);
    const Eigen::Vector3d a_com = A.tail<3>() + alpha.cross(c) + w.cross(v_com);
    const Eigen::Vector3d F = b.mass_kg * (a_com - model.gravity_m_s2);
    const Eigen::Vector3d N = I * alpha + w.cross(I * w);
    Vector6d& f = ws.force[j.child_body];
    f << N + c.cross(F), F;
    if (!external.empty()) f -= external[j.child_body];
  }
  // Backward sweep: each joint carries the wrench of its whole subtree.
  for (int k = static_cast<int>(model.joints.size()) - 1; k >= 0; --k) {
    const Joint& j = model.joints[k];
    const Vector6d& f = ws.force[j.child_body];
    for (int c : j.coordinates) {
      double t = 0;
      for (int r = 0; r < 6; ++r) t += ws.S.columns(r, c).a * f[r];
      tau[c] = t;
    }
    if (j.parent_body > 0) ws.force[j.parent_body] += f;
  }
}

}  // namespace cpgait
