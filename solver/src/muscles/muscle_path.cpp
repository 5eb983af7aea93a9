#include "cpgait/muscles/muscle_path.h"

namespace cpgait {
namespace {

// Position of a path point in ground and its Jacobian (3 x nq) with respect to all coordinates.
void point_and_jacobian(const Model& model, const PathPoint& p, const double* q, const KinematicsWorkspace<double>& ws,
                        const MotionSubspace& S, Eigen::Vector3d& x, Eigen::Matrix3Xd& J) {
  const auto& B = ws.body_in_ground[p.body];
  x = B.rotation * path_point_location(p, q) + B.translation_m;
  J.setZero();
  for (int body = p.body; body > 0;) {
    const Joint& j = model.joints[model.bodies[body].joint];
    for (int c : j.coordinates) J.col(c) = S.columns.col(c).head<3>().cross(x) + S.columns.col(c).tail<3>();
    body = j.parent_body;
  }
  if (p.kind == PathPoint::Kind::kMoving)
    for (int a = 0; a < 3; ++a)
      if (p.moving_coordinates[a] >= 0)
        J.col(p.moving_coordinates[a]) +=
            B.rotation.col(a) * p.moving_functions[a].derivative(q[p.moving_coordinates[a]]);
}

}  // namespace

void muscle_path_geometry(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                          const MotionSubspace& S, MusclePathGeometry& out) {
  const int nq = model.num_coordinates();
  Eigen::Matrix3Xd J_prev(3, nq), J(3, nq);
  Eigen::Vector3d x_prev, x;
  const Eigen::Map<const Eigen::VectorXd> qdot(qd, nq);
  for (std::size_t m = 0; m < model.muscles.size(); ++m) {
    double length = 0;
    Eigen::RowVectorXd dL_dq = Eigen::RowVectorXd::Zero(nq);
    bool have_previous = false;
    for (const PathPoint& p : model.muscles[m].path) {
      if (p.kind == PathPoint::Kind::kConditional && !path_point_active(p, q[p.coordinate])) continue;
      point_and_jacobian(model, p, q, ws, S, x, J);
      if (have_previous) {
        const Eigen::Vector3d d = x - x_prev;
        const double n = d.norm();
        length += n;
        if (n > 0) dL_dq += (d / n).transpose() * (J - J_prev);
      }
      x_prev = x;
      J_prev = J;
      have_previous = true;
    }
    out.length_m[m] = length;
    out.moment_arm_m.row(m) = -dL_dq;
    out.lengthening_speed_m_s[m] = dL_dq.dot(qdot);
  }
}

}  // namespace cpgait
