#include "cpgait/gait/standing_balance.h"

#include <algorithm>
#include <cmath>

namespace cpgait {

namespace {

// How far the pelvis moves along `direction` per unit of coordinate c, its foot held: the ankle turns
// the body above it as one (about the joint's axis, the pelvis with it); a hip swings the leg under a
// level pelvis, which moves as the foot would have, reversed.
double pelvis_shift(const MotionSubspace& S, int c, const Eigen::Vector3d& pelvis, const Eigen::Vector3d& foot, bool hip,
                    const Eigen::Vector3d& direction) {
  return -point_velocity_column(S, c, hip ? foot : pelvis).dot(direction);
}

}  // namespace

StandingJoints standing_joints(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs,
                               const KinematicsWorkspace<double>& kin, const MotionSubspace& S) {
  StandingJoints j;
  j.body_coordinates.resize(model.bodies.size());
  for (std::size_t b = 1; b < model.bodies.size(); ++b) j.body_coordinates[b] = ancestor_coordinates(model, static_cast<int>(b));
  if (!legs.valid()) return j;
  const Eigen::Vector3d along = horizontal_heading(kin, legs.pelvis_body), across = along.cross(Eigen::Vector3d::UnitY());
  for (int side = 0; side < 2; ++side) {
    // The foot: the side's sphere-carrying body nearest the pelvis.
    int foot = -1;
    for (int s : legs.spheres[side]) {
      const int body = contacts.spheres[s].body;
      if (foot < 0 || j.body_coordinates[body].size() < j.body_coordinates[foot].size()) foot = body;
    }
    const auto& hip = legs.hip[side];
    for (int c : j.body_coordinates[foot]) {  // root first: the last match is nearest the foot
      if (legs.is_root(c) || std::find(hip.begin(), hip.end(), c) != hip.end() || !model.coordinates[c].is_angle()) continue;
      const Eigen::Vector3d w = S.columns.col(c).head<3>();
      if (w.norm() > 1e-9 && std::abs(w.normalized().dot(across)) > std::sqrt(0.5)) j.ankle[side] = c;
    }
    double best = std::sqrt(0.5);
    for (int c : hip) {
      const Eigen::Vector3d w = S.columns.col(c).head<3>();
      if (w.norm() > 1e-9 && std::abs(w.normalized().dot(along)) > best) best = std::abs(w.normalized().dot(along)), j.hip[side] = c;
    }
  }
  return j;
}

void standing_balance_feedback(const Model& model, const ContactSet& contacts, const SimbiconLegs& legs, const StandingJoints& joints,
                               const StandingBalanceGains& g, const KinematicsWorkspace<double>& kin, const MotionSubspace& S,
                               const Eigen::VectorXd& u, double share, Eigen::VectorXd& e) {
  if (!legs.valid() || share <= 0) return;
  // The centre of mass and its velocity; the middle of the feet and each foot's.
  Eigen::Vector3d com = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
  double mass = 0;
  for (std::size_t b = 1; b < model.bodies.size(); ++b) {
    const auto& X = kin.body_in_ground[b];
    const Eigen::Vector3d p = X.rotation * model.bodies[b].com_m + X.translation_m;
    Eigen::Vector3d vb = Eigen::Vector3d::Zero();
    for (int c : joints.body_coordinates[b]) vb += point_velocity_column(S, c, p) * u[c];
    com += model.bodies[b].mass_kg * p;
    v += model.bodies[b].mass_kg * vb;
    mass += model.bodies[b].mass_kg;
  }
  com /= mass;
  v /= mass;
  Eigen::Vector3d middle = Eigen::Vector3d::Zero(), foot[2];
  for (int side = 0; side < 2; ++side) {
    foot[side].setZero();
    for (int s : legs.spheres[side]) foot[side] += sphere_centre_m(kin, contacts.spheres[s]);
    foot[side] /= static_cast<double>(legs.spheres[side].size());
    middle += 0.5 * foot[side];
  }
  const double h = std::max(0.1, com.y() - middle.y());
  const Eigen::Vector3d along = horizontal_heading(kin, legs.pelvis_body), across = along.cross(Eigen::Vector3d::UnitY());
  const double lean_along = (com - middle).dot(along) / h, rate_along = v.dot(along) / h;
  const double lean_across = (com - middle).dot(across) / h, rate_across = v.dot(across) / h;
  const double back = share * (g.ankle_kp * lean_along + g.ankle_kv * rate_along);
  const double over = share * (g.hip_kp * lean_across + g.hip_kv * rate_across);
  const Eigen::Vector3d pelvis = kin.body_in_ground[legs.pelvis_body].translation_m;
  for (int side = 0; side < 2; ++side) {
    if (const int c = joints.ankle[side]; c >= 0) e[c] -= pelvis_shift(S, c, pelvis, foot[side], false, along) >= 0 ? back : -back;
    if (const int c = joints.hip[side]; c >= 0) e[c] -= pelvis_shift(S, c, pelvis, foot[side], true, across) >= 0 ? over : -over;
  }
}

}  // namespace cpgait
