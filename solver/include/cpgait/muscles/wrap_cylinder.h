#pragma once
// A straight path segment wrapped over a cylinder: OpenSim's WrapCylinder decisions (whether the
// segment wraps, which side, short or long way round, quadrant constraint, the cylinder's length),
// with the exact geodesic for the tangent points: unrolled, the path from p1 over the surface to p2
// is one straight line, so each tangent point sits at its circumferential share of the axial rise.
// OpenSim slides its tangent points towards the same geodesic until tangent within 0.1 degree.
//
// All in the cylinder's frame W (axis z, centred on the origin). Branches are taken on values, so a
// Ceres Jet differentiates the result exactly within a branch.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "cpgait/model/model.h"
#include "cpgait/scalar.h"

namespace cpgait {

// OpenSim's WrapAction codes, in its order.
enum class WrapStatus { kNoWrap = 0, kInsideRadius = 1, kWrapped = 2, kMandatoryWrap = 3 };

template <typename T>
struct SegmentWrap {
  WrapStatus status = WrapStatus::kNoWrap;
  Eigen::Matrix<T, 3, 1> r1, r2;  // tangent points in W (valid when status >= kWrapped)
  T surface_length_m = T(0.0);    // the helix from r1 to r2
  bool wraps() const { return status == WrapStatus::kWrapped || status == WrapStatus::kMandatoryWrap; }
};

namespace wrap_detail {

inline int dsign(double a) { return a >= 0.0 ? 1 : -1; }

// Closest points of the line through a,b (parameter s: 0 at a, 1 at b) and the line through c,d.
inline bool closest_points_of_lines(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                    const Eigen::Vector3d& d, Eigen::Vector3d& on_ab, double& s, Eigen::Vector3d& on_cd) {
  const Eigen::Vector3d u = b - a, v = d - c, w = a - c;
  const double uu = u.dot(u), uv = u.dot(v), vv = v.dot(v), uw = u.dot(w), vw = v.dot(w);
  const double den = uu * vv - uv * uv;
  if (den <= 1e-13 * uu * vv) return false;  // parallel
  s = (uv * vw - vv * uw) / den;
  const double t = (uu * vw - uv * uw) / den;
  on_ab = a + s * u;
  on_cd = c + t * v;
  return true;
}

}  // namespace wrap_detail

template <typename T>
SegmentWrap<T> wrap_cylinder(const WrapObject& cyl, const Eigen::Matrix<T, 3, 1>& p1, const Eigen::Matrix<T, 3, 1>& p2) {
  using std::atan2;
  using std::sqrt;
  using V3 = Eigen::Matrix<T, 3, 1>;
  SegmentWrap<T> out;
  const double R = cyl.radius_m, R2 = R * R;
  const Eigen::Vector3d a(scalar_value(p1[0]), scalar_value(p1[1]), scalar_value(p1[2]));
  const Eigen::Vector3d b(scalar_value(p2[0]), scalar_value(p2[1]), scalar_value(p2[2]));
  if (a.head<2>().squaredNorm() < R2 || b.head<2>().squaredNorm() < R2) {
    out.status = WrapStatus::kInsideRadius;
    return out;
  }
  // Where the segment passes closest to the axis (between the cylinder's ends).
  Eigen::Vector3d near_segment, near_axis;
  double s = -1;
  const bool crossing = wrap_detail::closest_points_of_lines(a, b, Eigen::Vector3d(0, 0, -0.5 * cyl.length_m),
                                                             Eigen::Vector3d(0, 0, 0.5 * cyl.length_m), near_segment, s, near_axis);
  const bool intersects = crossing && (near_segment - near_axis).squaredNorm() < R2 && s > 0.0 && s < 1.0;
  const bool constrained = cyl.quadrant_sign != 0;
  if (!constrained && !intersects) return out;
  out.status = intersects ? WrapStatus::kMandatoryWrap : WrapStatus::kWrapped;

  // The two tangent candidates of each point in the cross-section (a: +, b: - about the axis).
  auto candidates = [&](const Eigen::Vector3d& p, Eigen::Vector3d& ca, Eigen::Vector3d& cb) {
    const Eigen::Vector2d v = p.head<2>().normalized();
    const double rho = p.head<2>().norm(), along = R2 / rho, across = sqrt(R2 - along * along);
    const Eigen::Vector2d perp(-v.y(), v.x());
    ca << along * v + across * perp, p.z();
    cb << along * v - across * perp, p.z();
  };
  Eigen::Vector3d r1a, r1b, r2a, r2b;
  candidates(a, r1a, r1b);
  candidates(b, r2a, r2b);
  Eigen::Vector3d r1, r2;
  bool long_wrap = false;
  if (constrained) {
    const int ax = cyl.quadrant_axis, sg = cyl.quadrant_sign;
    using wrap_detail::dsign;
    if (dsign(a[ax]) == sg || dsign(b[ax]) == sg) {
      // A point on the constrained side: wrap if the segment cuts the cylinder, or if it crosses to
      // the other side with its closest approach there.
      if (!intersects && !(dsign(a[ax]) != dsign(b[ax]) && dsign(near_segment[ax]) != sg)) {
        out.status = WrapStatus::kNoWrap;
        return out;
      }
    }
    // Which pairing, (r1b, r2a) or (r1a, r2b): the one whose first point lies on the active side;
    // with both or neither there, the second points decide; with none on it, the smaller angle.
    const bool r1a_on = dsign(r1a[ax]) == sg, r1b_on = dsign(r1b[ax]) == sg;
    const bool r2a_on = dsign(r2a[ax]) == sg, r2b_on = dsign(r2b[ax]) == sg;
    auto angle = [](const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
      return std::acos(std::clamp(u.head<2>().normalized().dot(v.head<2>().normalized()), -1.0, 1.0));
    };
    bool pick_b_first;
    if (r1a_on && r1b_on) pick_b_first = r2a_on;
    else if (r1a_on || r1b_on) pick_b_first = r1b_on;
    else if (r2a_on || r2b_on) pick_b_first = r2a_on;
    else pick_b_first = !(angle(r1a, r2b) > angle(r1b, r2a));
    r1 = pick_b_first ? r1b : r1a;
    r2 = pick_b_first ? r2a : r2b;
    // Less than half way round or more: the tangent points' radial directions against the path's.
    const Eigen::Vector3d sum_path = (r1 - a) + (r2 - b);
    long_wrap = (r1 + r2).head<2>().dot(sum_path.head<2>()) < 0.0;
  } else {
    // The pair whose radial directions are closest: the short way round.
    const Eigen::Vector2d ua = r1a.head<2>().normalized(), ub = r1b.head<2>().normalized(),
                          va = r2a.head<2>().normalized(), vb = r2b.head<2>().normalized();
    const double d1 = ua.dot(va), d2 = ua.dot(vb), d3 = ub.dot(va), d4 = ub.dot(vb);
    if (d1 > d2 && d1 > d3 && d1 > d4) r1 = r1a, r2 = r2a;
    else if (d2 > d3 && d2 > d4) r1 = r1a, r2 = r2b;
    else if (d3 > d4) r1 = r1b, r2 = r2a;
    else r1 = r1b, r2 = r2b;
  }
  const bool r1_is_a = r1 == r1a, r2_is_a = r2 == r2a;

  // The geodesic on the values' scalar type: tangent points from the chosen sides.
  auto tangent = [&](const V3& p, bool plus) {
    const T rho2 = p[0] * p[0] + p[1] * p[1];
    const T along = T(R2) / rho2, across = sqrt(T(R2) * rho2 - T(R2 * R2)) / rho2;
    const T sg(plus ? 1.0 : -1.0);
    return V3(along * p[0] - sg * across * p[1], along * p[1] + sg * across * p[0], T(0.0));
  };
  V3 t1 = tangent(p1, r1_is_a), t2 = tangent(p2, r2_is_a);
  const T cross = t1[0] * t2[1] - t1[1] * t2[0], dot = t1[0] * t2[0] + t1[1] * t2[1];
  T angle = atan2(scalar_value(cross) >= 0 ? cross : -cross, dot);
  if (long_wrap) angle = T(2.0 * M_PI) - angle;
  const T arc = T(R) * angle;
  const T d1 = sqrt(p1[0] * p1[0] + p1[1] * p1[1] - T(R2)), d2 = sqrt(p2[0] * p2[0] + p2[1] * p2[1] - T(R2));
  const T unrolled = d1 + arc + d2, rise = p2[2] - p1[2];
  t1[2] = p1[2] + rise * d1 / unrolled;
  t2[2] = p1[2] + rise * (d1 + arc) / unrolled;
  const double half = 0.5 * cyl.length_m;
  const double z1 = scalar_value(t1[2]), z2 = scalar_value(t2[2]);
  if ((z1 < -half || z1 > half) && (z2 < -half || z2 > half)) {
    out.status = WrapStatus::kNoWrap;
    return out;
  }
  out.r1 = t1;
  out.r2 = t2;
  out.surface_length_m = sqrt(arc * arc + (t2[2] - t1[2]) * (t2[2] - t1[2]));
  return out;
}

}  // namespace cpgait
