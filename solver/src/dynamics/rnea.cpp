#include "cpgait/dynamics/rnea.h"

#include <algorithm>

namespace cpgait {

void rnea_kinematics(const Model& model, const double* q, const double* qd, DynamicsWorkspace& ws) {
  forward_kinematics(model, q, ws.kinematics);
  motion_subspace_and_rate(model, q, qd, ws.kinematics, ws.S, ws.velocity, ws.S_rate);
}

void kinematics_values(const DynamicsWorkspace& ws, KinematicsWorkspace<double>& kinematics, MotionSubspace& S) {
  kinematics.body_in_ground = ws.kinematics.body_in_ground;
  S.columns = ws.S.columns;
}

void rnea(const Model& model, const double* q, const double* qd, const double* qdd,
          const std::vector<Vector6d>& external, DynamicsWorkspace& ws, double* tau) {
  rnea_kinematics(model, q, qd, ws);
  rnea_from_kinematics(model, qd, qdd, external, ws, tau);
}

void rnea_from_kinematics(const Model& model, const double* qd, const double* qdd, const std::vector<Vector6d>& external,
                          DynamicsWorkspace& ws, double* tau) {
  // The body velocities are rnea_kinematics' (motion_subspace_and_rate propagates them).
  ws.acceleration[0].setZero();
  for (const Joint& j : model.joints) {
    const Vector6d& V = ws.velocity[j.child_body];
    Vector6d A = ws.acceleration[j.parent_body];
    for (int c : j.coordinates)
      for (int r = 0; r < 6; ++r) A[r] += ws.S.columns(r, c) * qdd[c] + ws.S_rate(r, c) * qd[c];
    ws.acceleration[j.child_body] = A;

    // Newton-Euler for the child body about its centre of mass, moved to the ground origin.
    const Body& b = model.bodies[j.child_body];
    const auto& X = ws.kinematics.body_in_ground[j.child_body];
    const Eigen::Matrix3d& R = X.rotation;
    const Eigen::Vector3d& p = X.translation_m;
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
  std::fill(tau, tau + model.num_coordinates(), 0.0);
  add_generalized_forces_of_wrenches(model, ws.S, ws.force, tau);
}

void add_generalized_forces_of_wrenches(const Model& model, const MotionSubspace& S, std::vector<Vector6d>& wrench, double* tau) {
  for (int k = static_cast<int>(model.joints.size()) - 1; k >= 0; --k) {
    const Joint& j = model.joints[k];
    const Vector6d& f = wrench[j.child_body];
    for (int c : j.coordinates) {
      double t = 0;
      for (int r = 0; r < 6; ++r) t += S.columns(r, c) * f[r];
      tau[c] += t;
    }
    if (j.parent_body > 0) wrench[j.parent_body] += f;
  }
}

}  // namespace cpgait
