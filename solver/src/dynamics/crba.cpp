#include "cpgait/dynamics/crba.h"

#include <vector>

namespace cpgait {

namespace {
Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}
}  // namespace

Matrix6d spatial_inertia_in_ground(const Body& b, const PoseT<double>& X) {
  const Eigen::Vector3d c = X.rotation * b.com_m + X.translation_m;
  const Eigen::Matrix3d Ic = X.rotation * b.inertia_kg_m2 * X.rotation.transpose();
  const double m = b.mass_kg;
  const Eigen::Vector3d mc = m * c;
  Matrix6d I;
  // Momentum of velocity (w, v at the origin): h = Ic w + c x m (v + w x c), p = m (v + w x c); the
  // top-left block Ic - m [c]x [c]x = Ic + m (|c|^2 1 - c c^T).
  I.topLeftCorner<3, 3>() = Ic - mc * c.transpose();
  I.topLeftCorner<3, 3>().diagonal().array() += mc.dot(c);
  I.topRightCorner<3, 3>() = skew(mc);
  I.bottomLeftCorner<3, 3>() = -I.topRightCorner<3, 3>();
  I.bottomRightCorner<3, 3>() = m * Eigen::Matrix3d::Identity();
  return I;
}

void crba(const Model& model, const KinematicsWorkspace<double>& ws, const MotionSubspace& S, Eigen::MatrixXd& M,
          std::vector<Matrix6d>& composite) {
  const int nq = model.num_coordinates();
  M.setZero(nq, nq);
  // Composite inertias, leaves first: each joint's child accumulates its subtree.
  composite.resize(model.bodies.size());
  composite[0].setZero();
  for (std::size_t b = 1; b < model.bodies.size(); ++b) composite[b] = spatial_inertia_in_ground(model.bodies[b], ws.body_in_ground[b]);
  for (int k = static_cast<int>(model.joints.size()) - 1; k >= 0; --k) {
    const Joint& j = model.joints[k];
    if (j.parent_body > 0) composite[j.parent_body] += composite[j.child_body];
  }
  for (const Joint& j : model.joints) {
    const Matrix6d& Ic = composite[j.child_body];
    for (int ci : j.coordinates) {
      const Eigen::Matrix<double, 6, 1> F = Ic * S.columns.col(ci);
      // This joint's coordinates and every ancestor joint's see the subtree's force.
      for (int body = j.child_body; body > 0;) {
        const Joint& a = model.joints[model.bodies[body].joint];
        for (int cj : a.coordinates) M(ci, cj) = M(cj, ci) = S.columns.col(cj).dot(F);
        body = a.parent_body;
      }
    }
  }
}

}  // namespace cpgait
