#pragma once
// gait2392 with a wrap cylinder for every muscle at every hip and knee it crosses, as the Rajagopal
// family of models wraps its thigh muscles: on the joint's parent body at the joint's centre, along
// the joint frame's z (the flexion axis), its radius 1.2 times the path's closest approach at the
// default pose (at most 90 % of the nearest path point's distance, and no cylinder under 5 mm), so
// that many paths press on their cylinders. For the benchmarks of paths
// with many wrap objects (none of ../shared's models has more than six).
#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <vector>

#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/model/model.h"

namespace cpgait::bench {

inline Model gait2392_with_wrap_cylinders(Model m) {
  const Eigen::VectorXd q0 = Eigen::VectorXd::Zero(m.num_coordinates());
  KinematicsWorkspace<double> ws(m);
  forward_kinematics(m, q0.data(), ws);
  auto below = [&](int body, int joint_child) {  // body is joint_child or one of its descendants
    for (int b = body; b > 0; b = m.joints[m.bodies[b].joint].parent_body)
      if (b == joint_child) return true;
    return false;
  };
  for (Muscle& mu : m.muscles) {
    for (const Joint& j : m.joints) {
      if (j.name.find("hip") == std::string::npos && j.name.find("knee") == std::string::npos) continue;
      bool in = false, out = false;
      for (const PathPoint& p : mu.path) (below(p.body, j.child_body) ? in : out) = true;
      if (!in || !out) continue;
      // The joint's centre (its child frame's origin: gait2392's knee translates with its angle) and
      // axis in ground, and the path's closest approach to them at the default pose.
      const auto& parent = ws.body_in_ground[j.parent_body];
      const auto& child = ws.body_in_ground[j.child_body];
      const Eigen::Vector3d c = child.rotation * j.child_offset.translation_m + child.translation_m;
      const Eigen::Vector3d u = parent.rotation * j.parent_offset.rotation.col(2);
      const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - u * u.transpose();
      auto ground = [&](const PathPoint& p) {
        return Eigen::Vector3d(ws.body_in_ground[p.body].rotation * p.location_m + ws.body_in_ground[p.body].translation_m);
      };
      double closest = std::numeric_limits<double>::infinity(), nearest_point = closest;
      for (std::size_t k = 0; k < mu.path.size(); ++k) {
        nearest_point = std::min(nearest_point, (P * (ground(mu.path[k]) - c)).norm());
        if (k + 1 == mu.path.size()) break;
        const Eigen::Vector3d a = P * (ground(mu.path[k]) - c), d = P * (ground(mu.path[k + 1]) - ground(mu.path[k]));
        const double s = d.squaredNorm() > 0 ? std::clamp(-a.dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
        closest = std::min(closest, (a + s * d).norm());
      }
      const double radius = std::min(1.2 * closest, 0.9 * nearest_point);
      if (radius < 0.005) continue;  // a path point on the axis (gait2392's patella): no room for a cylinder
      WrapObject w;
      w.name = mu.name + "_at_" + j.name;
      w.shape = WrapObject::Shape::kCylinder;
      w.body = j.parent_body;
      w.pose.rotation = j.parent_offset.rotation;
      w.pose.translation_m = parent.rotation.transpose() * (c - parent.translation_m);
      w.radius_m = radius;
      w.length_m = 0.5;
      PathWrap pw;
      pw.wrap_object = static_cast<int>(m.wrap_objects.size());
      m.wrap_objects.push_back(w);
      mu.wraps.push_back(pw);  // joints come parent first, so the hip's wrap precedes the knee's
    }
  }
  return m;
}

}  // namespace cpgait::bench
