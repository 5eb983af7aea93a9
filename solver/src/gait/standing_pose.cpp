#include "cpgait/gait/standing_pose.h"

#include <Eigen/Dense>
#include <algorithm>

#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"

namespace cpgait {

Eigen::VectorXd standing_pose(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs, const Eigen::VectorXd& q0,
                              double ground_height_m, StandingPoseSummary* summary) {
  Eigen::VectorXd q = q0;
  if (!legs.valid()) return q;
  KinematicsWorkspace<double> kin(model);
  forward_kinematics(model, q.data(), kin);
  auto lowest = [&](const KinematicsWorkspace<double>& k, int s) {
    return Eigen::Vector3d(sphere_centre_m(k, contacts.spheres[s]) - contacts.spheres[s].radius_m * Eigen::Vector3d::UnitY());
  };
  const Eigen::Vector3d along = horizontal_heading(kin, legs.pelvis_body);
  // Each foot's rearmost and foremost spheres and its heading at the start; the unknowns.
  int rear[2], front[2];
  Eigen::Vector3d across0[2];
  std::vector<int> unknowns = legs.pelvis_translations;
  for (int side = 0; side < 2; ++side) {
    rear[side] = front[side] = legs.spheres[side].front();
    for (int s : legs.spheres[side]) {
      if (lowest(kin, s).dot(along) < lowest(kin, rear[side]).dot(along)) rear[side] = s;
      if (lowest(kin, s).dot(along) > lowest(kin, front[side]).dot(along)) front[side] = s;
    }
    Eigen::Vector3d d = lowest(kin, front[side]) - lowest(kin, rear[side]);
    d.y() = 0;
    across0[side] = (d.norm() > 1e-6 ? d.normalized() : along).cross(Eigen::Vector3d::UnitY());
    for (int c : ancestor_coordinates(model, contacts.spheres[rear[side]].body)) {
      const bool dependent = std::any_of(model.couplers.begin(), model.couplers.end(), [c](const CoordinateCoupler& k) { return k.dependent == c; });
      if (!legs.is_root(c) && !dependent && !model.coordinates[c].locked && std::find(unknowns.begin(), unknowns.end(), c) == unknowns.end())
        unknowns.push_back(c);
    }
  }
  auto residuals = [&](const Eigen::VectorXd& qq) {
    forward_kinematics(model, qq.data(), kin);
    Eigen::VectorXd r(8);
    Eigen::Vector3d feet = Eigen::Vector3d::Zero();
    for (int side = 0; side < 2; ++side) {
      const Eigen::Vector3d a = lowest(kin, rear[side]), b = lowest(kin, front[side]);
      r.segment<3>(3 * side) << a.y() - ground_height_m, b.y() - ground_height_m, (b - a).dot(across0[side]);
      feet += 0.5 * (a + b);
    }
    const Eigen::Vector3d com = centre_of_mass_m(model, kin) - 0.5 * feet;
    r.tail<2>() << com.x(), com.z();
    return r;
  };
  const Eigen::Index n = static_cast<Eigen::Index>(unknowns.size());
  Eigen::MatrixXd J(8, n);
  Eigen::VectorXd r = residuals(q);
  int it = 0;
  for (; it < 60 && r.cwiseAbs().maxCoeff() > 1e-7; ++it) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double h = 1e-6;
      Eigen::VectorXd qp = q, qm = q;
      qp[unknowns[j]] += h;
      qm[unknowns[j]] -= h;
      J.col(j) = (residuals(qp) - residuals(qm)) / (2 * h);
    }
    // The pose nearest the start (least squares over the unknowns) that meets the linearised residuals:
    // dq = -(q - q0) + J^+ (J (q - q0) - r), its step bounded to 0.2 (rad or m).
    Eigen::VectorXd away(n);
    for (Eigen::Index j = 0; j < n; ++j) away[j] = q[unknowns[j]] - q0[unknowns[j]];
    Eigen::VectorXd dq = -away + J.transpose() * (J * J.transpose() + 1e-9 * Eigen::MatrixXd::Identity(8, 8)).ldlt().solve(J * away - r);
    if (dq.cwiseAbs().maxCoeff() > 0.2) dq *= 0.2 / dq.cwiseAbs().maxCoeff();
    for (Eigen::Index j = 0; j < n; ++j) q[unknowns[j]] += dq[j];
    r = residuals(q);
  }
  if (summary) summary->residual_m = r.cwiseAbs().maxCoeff(), summary->iterations = it;
  return q;
}

}  // namespace cpgait
