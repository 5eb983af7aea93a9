#include "cpgait/muscles/wrap_sphere.h"

#include <cmath>

namespace cpgait {

SegmentWrap<double> wrap_sphere(const WrapObject& sphere, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2) {
  using V3 = Eigen::Vector3d;
  SegmentWrap<double> out;
  const double R = sphere.radius_m;
  if (p1.norm() < R || p2.norm() < R) {
    out.status = WrapStatus::kInsideRadius;
    return out;
  }
  // The segment must cut the sphere (constrained or not).
  const V3 ri = p1 - p2, mp = -p2;
  const double a = ri.dot(ri), b = -2.0 * mp.dot(ri), c = mp.dot(mp) - R * R, disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return out;
  const double l1 = (-b + std::sqrt(disc)) / (2.0 * a), l2 = (-b - std::sqrt(disc)) / (2.0 * a);
  if (!(0.0 < l1 && l1 < 1.0) || !(0.0 < l2 && l2 < 1.0)) return out;
  // The plane through both points and the centre holds the great circle. A segment through the
  // centre leaves it undefined: OpenSim reuses the previous frame's wrap there; cpgait has no memory
  // of frames, so such a segment is left unwrapped.
  const V3 along = ri.normalized();
  const V3 normal_raw = along.cross(p2.normalized());
  if (normal_raw.norm() < 0.00001) return out;
  const V3 n = normal_raw.normalized();
  // Each point's two tangent candidates, at asin(R/d) either side of the direction to the centre.
  auto candidates = [&](const V3& p, V3& ta, V3& tb) {
    const double d = p.norm(), angle = std::asin(R / d), reach = d * std::cos(angle);
    const V3 y = (-p).normalized(), z = n.cross(y);
    ta = p + reach * (std::cos(angle) * y - std::sin(angle) * z);
    tb = p + reach * (std::cos(angle) * y + std::sin(angle) * z);
  };
  V3 r1a, r1b, r2a, r2b;
  candidates(p1, r1a, r1b);
  candidates(p2, r2a, r2b);
  const V3 u1a = r1a.normalized(), u1b = r1b.normalized(), u2a = r2a.normalized(), u2b = r2b.normalized();
  // The pair closest in angle: the short way round.
  const double j1 = u1a.dot(u2a), j2 = u1a.dot(u2b), j3 = u1b.dot(u2a), j4 = u1b.dot(u2b);
  V3 r1, r2, other1, other2;
  if (j1 > j2 && j1 > j3 && j1 > j4) r1 = r1a, r2 = r2a, other1 = r1b, other2 = r2b;
  else if (j2 > j3 && j2 > j4) r1 = r1a, r2 = r2b, other1 = r1b, other2 = r2a;
  else if (j3 > j4) r1 = r1b, r2 = r2a, other1 = r1a, other2 = r2b;
  else r1 = r1b, r2 = r2b, other1 = r1a, other2 = r2a;
  out.status = WrapStatus::kWrapped;
  bool far_side = false;
  const int axis = sphere.quadrant_axis, sign = sphere.quadrant_sign;
  if (sign != 0) {
    using wrap_detail::dsign;
    if (dsign(p1[axis]) == sign || dsign(p2[axis]) == sign) {
      // The closest point of the line to the centre, as a fraction from p1 towards p2.
      const double t = -p1.dot(p2 - p1) / (p2 - p1).squaredNorm();
      const V3 closest = p1 + t * (p2 - p1);
      if (closest.squaredNorm() < R * R && t > 0.0 && t < 1.0) out.status = WrapStatus::kMandatoryWrap;
      else if (!(dsign(p1[axis]) != dsign(p2[axis]) && dsign(closest[axis]) != sign)) return SegmentWrap<double>{};
    }
    if (dsign(p1[axis]) != sign || dsign(p2[axis]) != sign) {
      // Tangent points towards the constrained side, flipped when the pull points away from it.
      const V3 towards = (-p1 - p2).normalized();
      r1 = u1a.dot(towards) > u1b.dot(towards) ? r1a : r1b;
      other1 = r1 == r1a ? r1b : r1a;
      r2 = u2a.dot(towards) > u2b.dot(towards) ? r2a : r2b;
      other2 = r2 == r2a ? r2b : r2a;
      if (((r1 - p1) + (r2 - p2)).normalized()[axis] * sign < 0.0) std::swap(r1, other1), std::swap(r2, other2);
      far_side = (r1 + r2).dot((r1 - p1) + (r2 - p2)) < 0.0;
    }
  }
  double angle = std::acos(std::clamp(r1.normalized().dot(r2.normalized()), -1.0, 1.0));
  // OpenSim negates the long way's angle here, which makes its length negative; the arc is 2 pi - angle.
  if (far_side) angle = 2 * M_PI - angle;
  out.r1 = r1;
  out.r2 = r2;
  out.surface_length_m = R * angle;
  return out;
}

}  // namespace cpgait
