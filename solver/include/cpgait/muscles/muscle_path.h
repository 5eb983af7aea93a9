#pragma once
// Musculotendon path geometry: the active path points (conditional points switch on their
// coordinate's range, moving points follow their functions), wrapping surfaces, path length,
// lengthening speed and moment arms r = -dL/dq.
//
// path_length<T> runs on any scalar (Ceres Jets differentiate it exactly); muscle_path_geometry
// computes the same derivative analytically from the motion subspace for speed, and the tests hold
// the two equal.
#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/model.h"
#include "cpgait/muscles/wrap_cylinder.h"
#include "cpgait/muscles/wrap_ellipsoid.h"
#include "cpgait/muscles/wrap_sphere.h"
#include "cpgait/muscles/wrap_torus.h"

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

// A point of the path as it currently runs: an active path point, or a tangent point where the path
// meets or leaves a wrapping surface (it moves with the surface's body).
template <typename T>
struct PathVertex {
  int body = 0;
  Eigen::Matrix<T, 3, 1> x_ground;
  const PathPoint* point = nullptr;  // nullptr for a tangent point
  int path_index = -1;               // the point's index in Muscle::path
  int wrap = -1;                     // tangent points: index in Muscle::wraps
  T surface_length_m = T(0.0);       // on a wrap's first tangent point: the length over the surface to the second
};

// One segment over one surface. The sphere, the ellipsoid and the torus are computed in doubles: on a Jet their
// tangent points stay fixed on the surface's body, which is how their moment arms are defined (and,
// for the sphere's geodesic, the exact derivative).
template <typename T>
SegmentWrap<T> wrap_segment(const WrapObject& obj, PathWrap::Method method, const Eigen::Matrix<T, 3, 1>& a,
                            const Eigen::Matrix<T, 3, 1>& b) {
  if (obj.shape == WrapObject::Shape::kCylinder) return wrap_cylinder(obj, a, b);
  auto in_doubles = [&](const Eigen::Vector3d& av, const Eigen::Vector3d& bv) {
    return obj.shape == WrapObject::Shape::kSphere  ? wrap_sphere(obj, av, bv)
           : obj.shape == WrapObject::Shape::kTorus ? wrap_torus(obj, av, bv)
                                                    : wrap_ellipsoid(obj, method, av, bv);
  };
  if constexpr (std::is_same_v<T, double>) {
    return in_doubles(a, b);
  } else {
    const Eigen::Vector3d av(scalar_value(a[0]), scalar_value(a[1]), scalar_value(a[2]));
    const Eigen::Vector3d bv(scalar_value(b[0]), scalar_value(b[1]), scalar_value(b[2]));
    const SegmentWrap<double> w = in_doubles(av, bv);
    SegmentWrap<T> out;
    out.status = w.status;
    out.r1 = w.r1.cast<T>();
    out.r2 = w.r2.cast<T>();
    out.surface_length_m = T(w.surface_length_m);
    return out;
  }
}

// Length along a current path: straight between points, over the surface between a wrap's two points.
template <typename T>
T current_path_length(const std::vector<PathVertex<T>>& path) {
  using std::sqrt;
  T length(0.0);
  for (std::size_t i = 0; i + 1 < path.size(); ++i)
    length += (path[i].wrap >= 0 && path[i + 1].wrap == path[i].wrap) ? path[i].surface_length_m
                                                                      : T(sqrt((path[i + 1].x_ground - path[i].x_ground).squaredNorm()));
  return length;
}

// OpenSim's GeometryPath::applyWrapObjects: each wrap, in order, wraps the segment of its range that
// must wrap (the first that cuts the surface) or else lengthens the path least; with two or more
// wraps, repeated until the length settles (0.5 mm, at most 8 passes) as OpenSim does.
// `muscle`: a Muscle or a PathSpring (anything with `path` and `wraps`).
template <typename T, typename PathOwner>
void current_path(const Model& model, const PathOwner& muscle, const T* q, const KinematicsWorkspace<T>& ws,
                  std::vector<PathVertex<T>>& path) {
  using std::sqrt;
  using V3 = Eigen::Matrix<T, 3, 1>;
  path.clear();
  for (std::size_t k = 0; k < muscle.path.size(); ++k) {
    const PathPoint& p = muscle.path[k];
    if (p.kind == PathPoint::Kind::kConditional && !path_point_active(p, scalar_value(q[p.coordinate]))) continue;
    const auto& B = ws.body_in_ground[p.body];
    PathVertex<T> v;
    v.body = p.body;
    v.x_ground = B.rotation * path_point_location(p, q) + B.translation_m;
    v.point = &p;
    v.path_index = static_cast<int>(k);
    path.push_back(v);
  }
  const int nw = static_cast<int>(muscle.wraps.size());
  if (nw == 0) return;
  auto remove_wrap = [&](int w) {
    for (std::size_t j = 0; j < path.size(); ++j)
      if (path[j].wrap == w) {
        path.erase(path.begin() + j, path.begin() + j + 2);
        return;
      }
  };
  std::vector<int> order(nw), result(nw, 0);
  for (int i = 0; i < nw; ++i) order[i] = i;
  double last_length = std::numeric_limits<double>::infinity();
  const int passes = nw < 2 ? 1 : 8;
  const int n_points = static_cast<int>(muscle.path.size());
  for (int pass = 0; pass < passes; ++pass) {
    for (int i = 0; i < nw; ++i) {
      const int w = order[i];
      const PathWrap& pw = muscle.wraps[w];
      const WrapObject& obj = model.wrap_objects[pw.wrap_object];
      result[i] = 0;
      remove_wrap(w);
      if (!obj.active) continue;
      // The range's first and last active points, found in the current path.
      const int first = pw.start_point < 1 ? 0 : pw.start_point - 1;
      const int last = pw.end_point < 1 ? n_points - 1 : pw.end_point - 1;
      int start = -1, end = -1;
      for (int j = 0; j < static_cast<int>(path.size()); ++j) {
        const int k = path[j].path_index;
        if (path[j].point && k >= first && k <= last) {
          if (start < 0) start = j;
          end = j;
        }
      }
      if (start < 0) continue;
      // The wrap surface's frame W in ground.
      const auto& B = ws.body_in_ground[obj.body];
      const Eigen::Matrix<T, 3, 3> R_GW = B.rotation * obj.pose.rotation.cast<T>();
      const V3 o_GW = B.rotation * obj.pose.translation_m.cast<T>() + B.translation_m;
      SegmentWrap<T> best;
      int best_after = -1;
      double least_change = std::numeric_limits<double>::infinity();
      for (int j = start; j < end; ++j) {
        if (path[j].wrap >= 0 && path[j].wrap == path[j + 1].wrap) continue;
        const V3 a = R_GW.transpose() * (path[j].x_ground - o_GW), b = R_GW.transpose() * (path[j + 1].x_ground - o_GW);
        const SegmentWrap<T> sw = wrap_segment(obj, pw.method, a, b);
        result[i] = static_cast<int>(sw.status);
        if (sw.status == WrapStatus::kMandatoryWrap) {
          best = sw;
          best_after = j;
          break;
        }
        if (sw.status == WrapStatus::kWrapped) {
          const double change = scalar_value(T(sqrt((sw.r1 - a).squaredNorm())) + sw.surface_length_m +
                                             T(sqrt((b - sw.r2).squaredNorm())) - T(sqrt((b - a).squaredNorm())));
          if (change < least_change) {
            least_change = change;
            best = sw;
            best_after = j;
          }
        }
      }
      if (best_after < 0) continue;
      PathVertex<T> t1, t2;
      t1.body = t2.body = obj.body;
      t1.wrap = t2.wrap = w;
      t1.x_ground = R_GW * best.r1 + o_GW;
      t2.x_ground = R_GW * best.r2 + o_GW;
      t1.surface_length_m = best.surface_length_m;
      path.insert(path.begin() + best_after + 1, {t1, t2});
    }
    const double L = scalar_value(current_path_length(path));
    if (std::abs(L - last_length) < 0.0005) break;
    last_length = L;
    // OpenSim's retry: the first surface missed and the second enclosed a point, so swap the two.
    if (pass == 0 && nw > 1 && result[0] == static_cast<int>(WrapStatus::kNoWrap) &&
        result[1] == static_cast<int>(WrapStatus::kInsideRadius)) {
      order[0] = 1;
      order[1] = 0;
      remove_wrap(0);
    }
  }
}

template <typename T, typename PathOwner>
T path_length(const Model& model, const PathOwner& muscle, const T* q, const KinematicsWorkspace<T>& ws) {
  std::vector<PathVertex<T>> path;
  current_path(model, muscle, q, ws, path);
  return current_path_length(path);
}

struct MusclePathGeometry {
  Eigen::VectorXd length_m;          // per muscle
  Eigen::VectorXd lengthening_speed_m_s;
  Eigen::MatrixXd moment_arm_m;      // muscles x coordinates: -dL/dq (m, or dimensionless for translations)
  explicit MusclePathGeometry(const Model& m)
      : length_m(m.muscles.size()), lengthening_speed_m_s(m.muscles.size()),
        moment_arm_m(m.muscles.size(), m.num_coordinates()) {}
};

// The coordinates a muscle's moment arm can be nonzero on, ascending, whatever the pose: those of the
// joints between its path's bodies (its points' and its wrap surfaces') below their common ancestor,
// and those its moving points follow. muscle_path_geometry writes zeros elsewhere.
std::vector<int> spanned_coordinates(const Model& model, const Muscle& muscle);

// ws and S from forward_kinematics / motion_subspace at q.
void muscle_path_geometry(const Model& model, const double* q, const double* qd, const KinematicsWorkspace<double>& ws,
                          const MotionSubspace& S, MusclePathGeometry& out);

// The same generalized forces without the moment-arm matrix, for evaluations that only need the
// muscles' effect on the skeleton (an integrator's stages): R^T F as spatial forces on the path's
// bodies, mapped by J^T once for all muscles (~1/5 of forming R for gait2392's 92 x 23).
// `path` from current_path at the pose in ws. Spatial vectors are in ground at the ground origin:
// velocities angular then linear, forces moment then force.
using SpatialVector = Eigen::Matrix<double, 6, 1>;
// A straight segment of a current path that can stretch (not fixed on one body, not over a wrap
// surface): its ends' indices in the path, d = x_v - x_u (ground, m) and n = |d| > 0.
struct StretchingSegment {
  int u = 0, v = 0;
  Eigen::Vector3d d;
  double n = 0;
};
// The path's length (m), as current_path_length sums it, and its stretching segments, in one pass:
// the lengthening speed and the tension below both work on the segments.
double current_path_segments(const std::vector<PathVertex<double>>& path, std::vector<StretchingSegment>& segments);
// dL/dt (m/s) = dL/dq qd: each stretching segment's end velocities along it (tangent points move with
// their surface's body, as muscle_path_geometry counts them), plus moving points' own motion.
double current_path_lengthening_speed(const std::vector<PathVertex<double>>& path,
                                      const std::vector<StretchingSegment>& segments, const double* q, const double* qd,
                                      const KinematicsWorkspace<double>& ws,
                                      const std::vector<SpatialVector>& body_velocity);
// A tension (N) along the path: equal and opposite forces at each stretching segment's ends, added to
// body_wrench, and moving points' own generalized forces, added to tau. Mapped by J^T
// (add_generalized_forces_of_wrenches, rnea.h) they sum to -tension dL/dq.
void add_path_tension(const std::vector<PathVertex<double>>& path, const std::vector<StretchingSegment>& segments,
                      const double* q, const KinematicsWorkspace<double>& ws, double tension_N,
                      std::vector<SpatialVector>& body_wrench, double* tau);

// One path spring's or path actuator's length (m), lengthening speed (m/s; 0 when qd is null) and
// dL/dq (a row of nq), as the muscles'.
void path_geometry(const Model& model, const PathSpring& spring, const double* q, const double* qd,
                   const KinematicsWorkspace<double>& ws, const MotionSubspace& S, double& length_m,
                   double& lengthening_speed_m_s, Eigen::RowVectorXd& dL_dq);
void path_geometry(const Model& model, const PathActuator& actuator, const double* q, const double* qd,
                   const KinematicsWorkspace<double>& ws, const MotionSubspace& S, double& length_m,
                   double& lengthening_speed_m_s, Eigen::RowVectorXd& dL_dq);

}  // namespace cpgait
