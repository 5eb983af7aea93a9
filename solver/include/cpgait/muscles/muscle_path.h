#pragma once
// Musculotendon path geometry: the active path points (conditional points switch on their
// coordinate's range, moving points follow their functions), path length, lengthening speed and
// moment arms r = -dL/dq.
//
// path_length<T> runs on any scalar (Ceres Jets differentiate it exactly); muscle_path_geometry
// computes the same derivative analytically from the motion subspace for speed, and the tests hold
// the two equal.
#include <Eigen/Core>
#include <vector>

#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/model.h"

namespace cpgait {

inline bool path_point_active(const PathPoint& p, double q_coordinate) {
  return p.kind != PathPoint::Kind::kConditional || (q_coordinate >= p.range_min && q_coordinate <= p.range_max);
}

// Location of a path point in its body's frame.
template <typename T>
Eigen::Matrix<T, 3, 1> path_point_location(const PathPoint& p, const T* q) {
  if (p.kind != PathPoint::Kind::kMoving) return p.location_m.cast<T>();
  Eigen::Matrix<T, 3, 1> loc;
  for (int a = 0; a < 3; ++a)
    loc[a] = p.moving_coordinates[a] >= 0 ? p.moving_functions[a].value(q[p.moving_coordinates[a]])
                                          : T(p.moving_functions[a].value(0.0));
  return loc;
}

template <typename T>
T path_length(const Muscle& muscle, const T* q, const KinematicsWorkspace<T>& ws) {
  using std::sqrt;
  T length(0.0);
  bool have_previous = false;
  Eigen::Matrix<T, 3, 1> previous;
  for (const PathPoint& p : muscle.path) {
    if (p.kind == PathPoint::Kind::kConditional && !path_point_active(p, scalar_value(q[p.coordinate]))) continue;
    const auto& B = ws.body_in_ground[p.body];
    const Eigen::Matrix<T, 3, 1> x = B.rotation * path_point_location(p, q) + B.translation_m;
    if (have_previous) length += sqrt((x - previous).squaredNorm());
    previous = x;
    have_previous = true;
  }
  return length;
}

struct MusclePathGeometry {
  Eigen::VectorXd length_m;          // per muscle
  Eigen::VectorXd lengthening_speed_m_s;
  Eigen::MatrixXd moment_arm_m;      // muscles x coordinates: -dL/dq (m, or dimensionless for translations)
  explicit MusclePathGeometry(const Model& m)
      : length_m(m.muscles.size()), lengthening_speed_m_s(m.muscles.size()),
        moment_arm_m(m.muscles.size(), m.num_coordinates()) {}
};

// ws and S from forward_kinematics / motion_subspace at q.
void muscle_path_geometry(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                          const MotionSubspace& S, MusclePathGeometry& out);

}  // namespace cpgait
