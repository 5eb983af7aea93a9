#include "cpgait/gait/simbicon_balance.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace cpgait {

namespace {

// The mean centre of a side's spheres (ground frame).
Eigen::Vector3d foot_point(const ContactSet& contacts, const std::vector<int>& spheres, const KinematicsWorkspace<double>& kin) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int s : spheres) p += sphere_centre_m(kin, contacts.spheres[s]);
  return p / static_cast<double>(spheres.size());
}

// The rotation among `rotations` whose axis lies closest to `along` (unit), within 60 deg of it; -1:
// none. along_share: the axis' component along it (signed), to turn a roll into the coordinate's angle.
int closest_rotation(const MotionSubspace& S, const std::vector<int>& rotations, const Eigen::Vector3d& along, double* along_share) {
  int best = -1;
  double best_share = 0.5;  // |cos| of the axis' angle to the way: at least cos 60 deg
  for (int c : rotations) {
    const Eigen::Vector3d w = S.columns.col(c).head<3>();
    const double n = w.norm();
    if (!(n > 1e-12)) continue;
    const double w_along = w.dot(along);
    if (std::abs(w_along) / n >= best_share) best = c, best_share = std::abs(w_along) / n, *along_share = w_along;
  }
  return best;
}

}  // namespace

Eigen::Vector3d horizontal_heading(const KinematicsWorkspace<double>& kin, int body) {
  Eigen::Vector3d along = kin.body_in_ground[body].rotation.col(0);
  along.y() = 0;
  return along.norm() > 1e-9 ? Eigen::Vector3d(along.normalized()) : Eigen::Vector3d::UnitX();
}

bool SimbiconLegs::is_root(int c) const {
  return std::find(pelvis_rotations.begin(), pelvis_rotations.end(), c) != pelvis_rotations.end() ||
         std::find(pelvis_translations.begin(), pelvis_translations.end(), c) != pelvis_translations.end();
}

int side_of(const std::string& name) {
  if (name.size() >= 2 && name.compare(name.size() - 2, 2, "_r") == 0) return 0;
  if (name.size() >= 2 && name.compare(name.size() - 2, 2, "_l") == 0) return 1;
  return -1;
}

SimbiconLegs simbicon_legs(const Model& model, const ContactSet& contacts) {
  SimbiconLegs legs;
  for (const auto& j : model.joints)
    if (j.parent_body == 0) {
      legs.pelvis_body = j.child_body;
      for (int c : j.coordinates) (model.coordinates[c].is_angle() ? legs.pelvis_rotations : legs.pelvis_translations).push_back(c);
      break;
    }
  if (legs.pelvis_body <= 0) return legs;
  int thigh[2] = {-1, -1};
  for (const auto& j : model.joints) {
    if (j.parent_body != legs.pelvis_body) continue;
    const int side = side_of(model.bodies[j.child_body].name);
    if (side >= 0 && legs.hip[side].empty()) {
      thigh[side] = j.child_body;
      for (int c : j.coordinates)
        if (model.coordinates[c].is_angle()) legs.hip[side].push_back(c);
    }
  }
  // Each thigh's subtree, whatever order the joints come in.
  for (int side = 0; side < 2; ++side) {
    if (thigh[side] < 0) continue;
    std::vector<bool> in_leg(model.bodies.size(), false);
    in_leg[thigh[side]] = true;
    for (bool grew = true; grew;) {
      grew = false;
      for (const auto& j : model.joints)
        if (in_leg[j.parent_body] && !in_leg[j.child_body]) {
          in_leg[j.child_body] = grew = true;
          for (int c : j.coordinates)
            if (model.coordinates[c].is_angle()) legs.below_hip[side].push_back(c);
        }
    }
  }
  for (std::size_t s = 0; s < contacts.spheres.size(); ++s) {
    const int side = side_of(contacts.spheres[s].name);
    if (side >= 0) legs.spheres[side].push_back(static_cast<int>(s));
  }
  return legs;
}

bool rolls_both_feet(const Model& model, const SimbiconLegs& legs) {
  if (!legs.valid()) return false;
  const Eigen::VectorXd q = model.default_coordinates();
  KinematicsWorkspace<double> kin(model);
  forward_kinematics(model, q.data(), kin);
  MotionSubspace S(model);
  motion_subspace(model, q.data(), kin, S);
  const Eigen::Vector3d along = horizontal_heading(kin, legs.pelvis_body);
  double share = 0;
  return closest_rotation(S, legs.below_hip[0], along, &share) >= 0 && closest_rotation(S, legs.below_hip[1], along, &share) >= 0;
}

void simbicon_balance_feedback(const ContactSet& contacts, const SimbiconLegs& legs, const SimbiconGains& g,
                               const KinematicsWorkspace<double>& kin, const MotionSubspace& S, const Eigen::VectorXd& u,
                               const KinematicsWorkspace<double>& reference_kin, const Eigen::VectorXd& e_pelvis,
                               const Eigen::VectorXd& ed_pelvis, const Eigen::Vector3d& v_ref,
                               const std::vector<Eigen::Vector3d>& contact_force_N, double stance_N, Eigen::VectorXd& e,
                               Eigen::VectorXd& ed) {
  if (!legs.valid() || !g.any()) return;
  double load[2] = {0, 0};
  for (int side = 0; side < 2; ++side)
    for (int s : legs.spheres[side]) load[side] += contact_force_N[s].y();
  const bool stance[2] = {load[0] > stance_N, load[1] > stance_N};
  const Eigen::Index np = static_cast<Eigen::Index>(legs.pelvis_rotations.size());
  Eigen::Matrix3Xd Jp(3, np);
  for (Eigen::Index i = 0; i < np; ++i) Jp.col(i) = S.columns.col(legs.pelvis_rotations[i]).head<3>();
  // The pelvis' offset from the stance foot (the more loaded one) and its velocity, horizontal.
  const int support = load[0] >= load[1] ? 0 : 1;
  const Eigen::Vector3d pelvis = kin.body_in_ground[legs.pelvis_body].translation_m;
  Eigen::Vector3d d_error = Eigen::Vector3d::Zero();
  if (stance[support])
    d_error = (pelvis - foot_point(contacts, legs.spheres[support], kin)) -
              (reference_kin.body_in_ground[legs.pelvis_body].translation_m - foot_point(contacts, legs.spheres[support], reference_kin));
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  for (int c : legs.pelvis_rotations) v += point_velocity_column(S, c, pelvis) * u[c];
  for (int c : legs.pelvis_translations) v += point_velocity_column(S, c, pelvis) * u[c];
  // Along and across the reference pelvis' heading (its x axis, horizontal).
  const Eigen::Vector3d along = horizontal_heading(reference_kin, legs.pelvis_body);
  const Eigen::Vector3d across = along.cross(Eigen::Vector3d::UnitY());
  const Eigen::Vector3d dv = v - v_ref;
  // A feedback's sideways term: gain_d (d - d_ref) + gain_v (v - v_ref) across the way.
  auto sideways = [&](double gain_d, double gain_v) { return gain_d * d_error.dot(across) + gain_v * dv.dot(across); };
  const Eigen::Vector3d shift = along * (g.sagittal_d * d_error.dot(along) + g.sagittal_v * dv.dot(along)) +
                                across * sideways(g.lateral_d, g.lateral_v);
  const bool placement = g.lateral_d != 0 || g.lateral_v != 0 || g.sagittal_d != 0 || g.sagittal_v != 0;
  const bool hold = g.stance_lateral_d != 0 || g.stance_lateral_v != 0;
  const bool ankle = g.ankle_d != 0 || g.ankle_v != 0;
  // The hip's change that moves the side's foot by `shift` against the pelvis (horizontal), least
  // squares. Not by the hip's turn about the (roughly vertical) thigh: with the knee bent it swings
  // the foot sideways by twisting the leg.
  auto move_foot = [&](int side, const Eigen::Vector3d& by) {
    const auto& hip = legs.hip[side];
    const Eigen::Index nh = static_cast<Eigen::Index>(hip.size());
    const Eigen::Vector3d p = foot_point(contacts, legs.spheres[side], kin);
    Eigen::Index twist = -1;
    if (nh == 3) {
      double most_vertical = -1;
      for (Eigen::Index i = 0; i < nh; ++i) {
        const Eigen::Vector3d w = S.columns.col(hip[i]).head<3>();
        const double vertical = std::abs(w.y()) / std::max(1e-12, w.norm());
        if (vertical > most_vertical) most_vertical = vertical, twist = i;
      }
    }
    Eigen::Matrix2Xd Jf(2, nh);
    for (Eigen::Index i = 0; i < nh; ++i) {
      const Eigen::Vector3d col = i == twist ? Eigen::Vector3d::Zero() : point_velocity_column(S, hip[i], p);
      Jf.col(i) = Eigen::Vector2d(col.x(), col.z());
    }
    const Eigen::VectorXd dh = Jf.completeOrthogonalDecomposition().solve(Eigen::Vector2d(by.x(), by.z()));
    for (Eigen::Index i = 0; i < nh; ++i) e[hip[i]] += dh[i];
  };
  // Rolls the side's foot about the walking direction by `angle` (rad; positive lowers the edge on the
  // `across` side) with the rotation below the hip whose axis is closest to that direction.
  auto roll_foot = [&](int side, double angle) {
    double best_along = 0;
    const int best = closest_rotation(S, legs.below_hip[side], along, &best_along);
    if (best >= 0) e[best] += angle / best_along;
  };
  // The hip's change that turns the femur as a change dp of the pelvis' rotations would: Jh^+ Jp.
  auto femur_map = [&](int side) -> Eigen::MatrixXd {
    const auto& hip = legs.hip[side];
    Eigen::Matrix3Xd Jh(3, static_cast<Eigen::Index>(hip.size()));
    for (Eigen::Index i = 0; i < Jh.cols(); ++i) Jh.col(i) = S.columns.col(hip[i]).head<3>();
    return Jh.completeOrthogonalDecomposition().solve(Jp);
  };
  for (int side = 0; side < 2; ++side) {
    const auto& hip = legs.hip[side];
    const Eigen::Index nh = static_cast<Eigen::Index>(hip.size());
    if (stance[side]) {
      if (hold && !stance[1 - side])
        move_foot(side, across * sideways(g.stance_lateral_d, g.stance_lateral_v));
      if (ankle && !stance[1 - side]) roll_foot(side, sideways(g.ankle_d, g.ankle_v));
      if (g.trunk_kp == 0 && g.trunk_kv == 0) continue;
      // The femur held still: Jh dh + Jp dp = 0.
      const Eigen::MatrixXd map = -femur_map(side);
      const Eigen::VectorXd dh = map * (g.trunk_kp * e_pelvis), dhd = map * (g.trunk_kv * ed_pelvis);
      for (Eigen::Index i = 0; i < nh; ++i) e[hip[i]] += dh[i], ed[hip[i]] += dhd[i];
    } else if (stance[1 - side]) {
      if (placement) move_foot(side, shift);
      if (g.swing_world == 0) continue;
      // The femur turned as the pelvis' error: Jh dh = Jp dp.
      const Eigen::MatrixXd map = g.swing_world * femur_map(side);
      const Eigen::VectorXd dh = map * e_pelvis, dhd = map * ed_pelvis;
      for (Eigen::Index i = 0; i < nh; ++i) e[hip[i]] += dh[i], ed[hip[i]] += dhd[i];
    }
  }
}

}  // namespace cpgait
