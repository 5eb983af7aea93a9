#include "cpgait/muscles/wrap_ellipsoid.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <vector>

namespace cpgait {
namespace {

using V3 = Eigen::Vector3d;

// OpenSim's constants (WrapEllipsoid.cpp, SimmMacros.h).
constexpr double kRoundoff = 2e-13;       // "equal within error"
constexpr double kTiny = 1e-8;            // tangent-point residual, in the normalised units
constexpr double kBlendMin = 0.7073;      // below: all fan (must exceed cos 45 deg)
constexpr double kBlendMax = 0.9;         // above: all Frans
constexpr int kFanSamples = 300;
constexpr double kBoundaryBlend = 0.3;
constexpr double kSegment_m = 0.001;      // chord length over the surface

bool near_zero(double x) { return std::abs(x) <= kRoundoff; }

// Closest point on the ellipse (x/a)^2 + (y/b)^2 = 1 to (u, v): Eberly's Newton iteration, with the
// points near the axes handled apart (Graphics Gems IV).
void closest_on_ellipse(double a, double b, double u, double v, double& x, double& y) {
  const double a2 = a * a, b2 = b * b, a2u2 = a2 * u * u, b2v2 = b2 * v * v;
  const bool near_x = near_zero(u), near_y = near_zero(v);
  if (near_x && near_y) {
    if (a < b) x = u < 0 ? -a : a, y = v;
    else x = u, y = v < 0 ? -b : b;
    return;
  }
  if (near_x) {
    if (a >= b || std::abs(v) >= b - a2 / b) {
      x = u;
      y = v >= 0 ? b : -b;
    } else {
      y = b2 * v / (b2 - a2);
      x = a * std::sqrt(std::abs(1 - (y / b) * (y / b)));
    }
    return;
  }
  if (near_y) {
    if (b >= a || std::abs(u) >= a - b2 / a) {
      x = u >= 0 ? a : -a;
      y = v;
    } else {
      x = a2 * u / (a2 - b2);
      y = b * std::sqrt(std::abs(1 - (x / a) * (x / a)));
    }
    return;
  }
  double t = (u / a) * (u / a) + (v / b) * (v / b) < 1.0 ? 0.0 : std::max(a, b) * std::sqrt(u * u + v * v);
  double P = 0, Q = 0;
  for (int i = 0; i < 64; ++i) {
    P = t + a2;
    Q = t + b2;
    const double f = P * P * Q * Q - a2u2 * Q * Q - b2v2 * P * P;
    if (std::abs(f) < 1e-9) break;
    t -= f / (2.0 * (P * Q * (P + Q) - a2u2 * Q - b2v2 * P));
  }
  x = a2 * u / P;
  y = b2 * v / Q;
}

// Closest point on the ellipsoid with semi-axes a to p. A point on a coordinate plane (or told to
// use one, special_axis) is solved in that plane's ellipse; dims_m picks the narrowest such section.
V3 closest_on_ellipsoid(const V3& a, const V3& p, const V3& dims_m, int special_axis = -1) {
  if (special_axis < 0) {
    double narrowest = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i)
      if (near_zero(p[i])) {
        const double sum = dims_m.sum() - dims_m[i];
        if (sum < narrowest) narrowest = sum, special_axis = i;
      }
  }
  V3 c = p;
  if (special_axis == 0) closest_on_ellipse(a[1], a[2], p[1], p[2], c[1], c[2]);
  else if (special_axis == 1) closest_on_ellipse(a[2], a[0], p[2], p[0], c[2], c[0]);
  else if (special_axis == 2) closest_on_ellipse(a[0], a[1], p[0], p[1], c[0], c[1]);
  if (special_axis >= 0) return c;
  const V3 a2 = a.cwiseProduct(a);
  const V3 a2p2 = a2.cwiseProduct(p.cwiseProduct(p));
  double t = (p.cwiseQuotient(a)).squaredNorm() < 1.0 ? 0.0 : a.maxCoeff() * p.norm();
  for (int i = 0; i < 64; ++i) {
    const double P = t + a2[0], Q = t + a2[1], R = t + a2[2];
    const double f = P * P * Q * Q * R * R - a2p2[0] * Q * Q * R * R - a2p2[1] * P * P * R * R - a2p2[2] * P * P * Q * Q;
    if (std::abs(f) < 1e-9) return V3(a2[0] * p[0] / P, a2[1] * p[1] / Q, a2[2] * p[2] / R);
    const double PQ = P * Q, PR = P * R, QR = Q * R;
    t -= f / (2.0 * (PQ * R * (QR + PR + PQ) - a2p2[0] * QR * (Q + R) - a2p2[1] * PR * (P + R) - a2p2[2] * PQ * (P + Q)));
  }
  return V3::Constant(std::numeric_limits<double>::quiet_NaN());  // OpenSim leaves the point unset here
}

// Moves r (starting on the surface) to where the line from p touches the ellipsoid within the
// plane vs.x + vs4 = 0: a damped Gauss-Newton on four residuals (in the plane, on the surface, and
// p and r on the tangent plane at r), as OpenSim's calcTangentPoint.
void tangent_point_in_plane(double p_outside, V3& r, const V3& p, const V3& a, const V3& vs, double vs4) {
  if (std::abs(p_outside) < 0.0001) {
    r = p;
    return;
  }
  const V3 inv_a2 = a.cwiseProduct(a).cwiseInverse();
  V3 n = 2.0 * r.cwiseProduct(inv_a2);
  double d = -n.dot(r);
  auto residuals = [&](Eigen::Vector4d& e) {
    n = 2.0 * r.cwiseProduct(inv_a2);
    e << vs.dot(r) + vs4, r.cwiseQuotient(a).squaredNorm() - 1.0, n.dot(r) + d, n.dot(p) + d;
    return e.squaredNorm();
  };
  Eigen::Vector4d e;
  double ssq = residuals(e), ssq_old = ssq, alpha = 0.01;
  for (int it = 0; ssq > kTiny && it < 50; ++it) {
    Eigen::Matrix4d J;  // J(i, j): d residual j / d unknown i (r x, y, z, d)
    for (int i = 0; i < 3; ++i) J.row(i) << vs[i], 2.0 * r[i] * inv_a2[i], 4.0 * r[i] * inv_a2[i], 2.0 * p[i] * inv_a2[i];
    J.row(3) << 0.0, 0.0, 1.0, 1.0;
    const double cos_p = (r - p).normalized().dot((-p).normalized());
    const double damp = cos_p > 0.1 ? 1.0 - std::pow(cos_p, 100) : 1.0;
    const Eigen::Vector4d g = -J * e;
    Eigen::Matrix4d JJ = J * J.transpose();
    const Eigen::Vector4d diag = JJ.diagonal();
    Eigen::Vector4d step = Eigen::Vector4d::Zero();
    for (int inner = 0; ssq >= ssq_old && inner < 1000; ++inner) {
      JJ.diagonal() = diag * (1.0 + alpha);
      step = damp * JJ.inverse() * g / 16.0;
      r += step.head<3>();
      d += step[3];
      ssq_old = ssq;
      ssq = residuals(e);
      alpha *= 4.0;
    }
    alpha /= 8.0;
    // Keep stepping, doubling, while it helps; then take back the last step.
    double factor = 0.5;
    for (int inner = 0; ssq <= ssq_old && inner < 1000; ++inner) {
      factor *= 2.0;
      r += step.head<3>() * factor;
      d += step[3] * factor;
      ssq_old = ssq;
      ssq = residuals(e);
    }
    r -= step.head<3>() * factor;
    d -= step[3] * factor;
    ssq = residuals(e);
    ssq_old = ssq;
  }
}

// The surface stretch from r1 to r2 in the plane (vs, vs4), the short or the long way round: points
// where rays from the plane's point a0 meet the surface, 1 mm apart; returns them, ends included.
std::vector<V3> surface_points(const V3& r1, const V3& r2, const V3& a, const V3& vs, double vs4, bool far_side,
                               double factor) {
  const double chord_m = (r2 - r1).norm() / factor;
  if (chord_m < kSegment_m) return {r1, r2};
  const int segments = std::min(499, static_cast<int>(chord_m / kSegment_m));
  int imax = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(vs[i]) > std::abs(vs[imax])) imax = i;
  V3 u = V3::Zero();
  u[imax] = 1.0;
  const V3 a0 = (-vs4 / vs.dot(u)) * u;
  const V3 ar1 = (r1 - a0).normalized(), ar2 = (r2 - a0).normalized();
  const double phi0 = std::acos(ar1.dot(ar2));
  const double dphi = far_side ? -(2 * M_PI - phi0) / segments : phi0 / segments;
  const V3 z = ar1.cross(ar2).normalized(), y = z.cross(ar1);
  std::vector<V3> pts{r1};
  const V3 f2 = a0.cwiseQuotient(a);
  for (int i = 1; i < segments; ++i) {
    const double phi = i * dphi;
    const V3 ray = std::cos(phi) * ar1 + std::sin(phi) * y;
    const V3 f1 = ray.cwiseQuotient(a);
    const double aa = f1.dot(f1), bb = 2.0 * f1.dot(f2), cc = f2.dot(f2) - 1.0;
    pts.push_back(a0 + (-bb + std::sqrt(bb * bb - 4.0 * aa * cc)) / (2.0 * aa) * ray);
  }
  pts.push_back(r2);
  return pts;
}

}  // namespace

SegmentWrap<double> wrap_ellipsoid(const WrapObject& ellipsoid, PathWrap::Method method, const V3& point1, const V3& point2) {
  SegmentWrap<double> out;
  // OpenSim scales everything so the semi-axes are near 1.
  const double factor = 3.0 / ellipsoid.dimensions_m.sum();
  const V3 p1 = point1 * factor, p2 = point2 * factor, a = ellipsoid.dimensions_m * factor;
  const double p1e = p1.cwiseQuotient(a).squaredNorm() - 1.0, p2e = p2.cwiseQuotient(a).squaredNorm() - 1.0;
  if (p1e < -0.0001 || p2e < -0.0001) {
    out.status = WrapStatus::kInsideRadius;
    return out;
  }
  if (std::abs((-p1).normalized().dot((-p2).normalized()) - 1.0) < 0.0001) return out;  // ends in line with the centre
  // The segment must cut the ellipsoid.
  const V3 p1p2 = p1 - p2;  // from p2 towards p1, as OpenSim parameterises it
  const V3 f1 = p1p2.cwiseQuotient(a), f2 = p2.cwiseQuotient(a);
  const double aa = f1.dot(f1), bb = 2.0 * f1.dot(f2), cc = f2.dot(f2) - 1.0, disc = bb * bb - 4.0 * aa * cc;
  if (disc < 0.0) return out;
  const double l1 = (-bb + std::sqrt(disc)) / (2.0 * aa), l2 = (-bb - std::sqrt(disc)) / (2.0 * aa);
  if (!(0.0 < l1 && l1 < 1.0) || !(0.0 < l2 && l2 < 1.0)) return out;
  V3 r1 = p2 + l1 * p1p2, r2 = p2 + l2 * p1p2;

  // The wrapping plane's surface point c1, and sv where it is seen from on the segment.
  const V3 r1r2 = r2 - r1;
  V3 mu = p1p2.normalized().cwiseAbs(), t;
  std::array<V3, 3> t_sv, t_c1;
  for (int i = 0; i < 3; ++i) {
    t[i] = -r1[i] / r1r2[i];
    t_sv[i] = r1 + t[i] * r1r2;
    t_c1[i] = closest_on_ellipsoid(a, t_sv[i], ellipsoid.dimensions_m, i);
  }
  int best = 0;
  for (int i = 1; i < 3; ++i)
    if (mu[i] > mu[best]) best = i;
  V3 c1 = V3::Zero(), sv = V3::Zero();
  double fan_weight = -std::numeric_limits<double>::infinity();
  if (method == PathWrap::Method::kHybrid || method == PathWrap::Method::kAxial) {
    if (method == PathWrap::Method::kHybrid && mu[best] > kBlendMin) {
      // Fade Frans' point out where its sv nears the segment's ends (it would leave the ellipsoid).
      double s = 1.0;
      if (t[best] < 0.0 || t[best] > 1.0) s = 0.0;
      else if (t[best] < kBoundaryBlend) s = t[best] / kBoundaryBlend;
      else if (t[best] > 1.0 - kBoundaryBlend) s = (1.0 - t[best]) / kBoundaryBlend;
      if (s < 1.0) mu[best] = kBlendMin + s * (mu[best] - kBlendMin);
    }
    if (method == PathWrap::Method::kAxial || mu[best] > kBlendMin) {
      c1 = t_c1[best];
      sv = t_sv[best];
    }
    if (method == PathWrap::Method::kHybrid && mu[best] < kBlendMax) {
      // The fan: the mean direction from points along r1-r2 to their closest surface points.
      const V3 mid = r1 + 0.5 * r1r2;
      V3 sum = V3::Zero();
      for (int i = 1; i < kFanSamples - 1; ++i) {
        const V3 s = r1 + (static_cast<double>(i) / kFanSamples) * r1r2;
        sum += (closest_on_ellipsoid(a, s, ellipsoid.dimensions_m) - s).normalized();
      }
      const V3 fan_c1 = mid + sum.normalized();
      if (mu[best] <= kBlendMin) {
        c1 = closest_on_ellipsoid(a, fan_c1, ellipsoid.dimensions_m);
        sv = mid;
        fan_weight = 1.0;
      } else {
        const double w = (mu[best] - kBlendMin) / (kBlendMax - kBlendMin);
        const V3 fan_surface = closest_on_ellipsoid(a, fan_c1, ellipsoid.dimensions_m);
        const V3 blended = w * c1 + (1.0 - w) * fan_surface;
        sv = w * sv + (1.0 - w) * mid;
        c1 = closest_on_ellipsoid(a, blended, ellipsoid.dimensions_m);
        fan_weight = 1.0 - w;
      }
    }
  } else {  // midpoint
    sv = r1 + 0.5 * r1r2;
    c1 = closest_on_ellipsoid(a, sv, ellipsoid.dimensions_m);
  }
  if (method != PathWrap::Method::kAxial || (t[best] > 0.0 && t[best] < 1.0)) r1 = r2 = c1;

  // Constrained to one side: reflect c1 onto it, part way back towards the plane for a fan's c1.
  const int axis = ellipsoid.quadrant_axis, sign = ellipsoid.quadrant_sign;
  if (sign != 0 && wrap_detail::dsign(c1[axis]) != sign) {
    const double original = c1[axis];
    c1[axis] = -c1[axis];
    r1 = r2 = c1;
    // OpenSim means to derive a weight for a Frans-only c1 here, but its test (-inf equal to -inf
    // within roundoff) is never true, so such a c1 is only reflected; cpgait does the same.
    fan_weight = std::min(fan_weight, 1.0);
    if (fan_weight > 0.0) {
      const double bisection = 0.5 * (original + c1[axis]);
      c1[axis] += fan_weight * (bisection - c1[axis]);
      c1 = closest_on_ellipsoid(a, c1, ellipsoid.dimensions_m);
    }
  }
  // The plane through p1, p2 and c1; the tangent points in it.
  const V3 vs = p1p2.cross(p1 - c1).normalized();
  const double vs4 = -vs.dot(c1);
  tangent_point_in_plane(p1e, r1, p1, a, vs, vs4);
  tangent_point_in_plane(p2e, r2, p2, a, vs, vs4);

  bool far_side = false;
  std::vector<V3> pts = surface_points(r1, r2, a, vs, vs4, far_side, factor);
  if (sign != 0 && pts.size() > 2) {
    // A wrap that leaves r1 back towards p1 (or r2 towards p2) went the wrong way round.
    const bool wrong = (p1 - r1).normalized().dot((pts[1] - r1).normalized()) > 0.0 ||
                       (p2 - r2).normalized().dot((pts[pts.size() - 2] - r2).normalized()) > 0.0;
    if (wrong) pts = surface_points(r1, r2, a, vs, vs4, far_side = true, factor);
  }
  double length = 0;
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) length += (pts[i + 1] - pts[i]).norm();
  out.status = WrapStatus::kMandatoryWrap;
  out.r1 = r1 / factor;
  out.r2 = r2 / factor;
  out.surface_length_m = length / factor;
  return out;
}

}  // namespace cpgait
