#include "cpgait/muscles/wrap_torus.h"

#include <cmath>
#include <optional>

namespace cpgait {
namespace {

// From `start` along the unit direction n, the local minimum of the squared distance to the circle
// of radius R about z, D(u) = |p(u)|^2 + R^2 - 2 R rho(u) (rho: distance from the axis), by
// safeguarded Newton steps. OpenSim's findClosestPoint solves D'(u) = 0 from u = 0 likewise.
Eigen::Vector3d closest_on_line(const Eigen::Vector3d& start, const Eigen::Vector3d& n, double R, double scale) {
  auto D = [&](double u) {
    const Eigen::Vector3d p = start + u * n;
    return p.squaredNorm() + R * R - 2 * R * p.head<2>().norm();
  };
  const double c3 = start.head<2>().dot(n.head<2>()), c4 = n.head<2>().squaredNorm();
  double u = 0;
  for (int it = 0; it < 100; ++it) {
    const Eigen::Vector3d p = start + u * n;
    const double rho = std::max(p.head<2>().norm(), 1e-12 * scale);
    const double g = 2 * (start.dot(n) + u) - 2 * R * (c3 + c4 * u) / rho;
    const double h = 2 - 2 * R * (c4 / rho - (c3 + c4 * u) * (c3 + c4 * u) / (rho * rho * rho));
    double step = h > 0 ? -g / h : (g > 0 ? -scale : scale);
    const double d0 = D(u);
    while (std::abs(step) > 1e-15 * scale && !(D(u + step) < d0)) step *= 0.5;
    if (std::abs(step) <= 1e-15 * scale) break;
    u += step;
    if (std::abs(step) < 1e-13 * scale) break;
  }
  return start + u * n;
}

}  // namespace

SegmentWrap<double> wrap_torus(const WrapObject& torus, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2) {
  const double R = torus.outer_radius_m;
  const double length = (p2 - p1).norm();
  if (!(length > 0)) return {};
  const Eigen::Vector3d n = (p2 - p1) / length;
  const double scale = length + p1.norm() + R;
  // Two passes, from each end, as OpenSim's findClosestPoint.
  const Eigen::Vector3d a1 = closest_on_line(p1, n, R, scale), a2 = closest_on_line(p2, -n, R, scale);
  auto distance = [&](const Eigen::Vector3d& a) { return a.squaredNorm() + R * R - 2 * R * a.head<2>().norm(); };
  std::optional<Eigen::Vector3d> best;
  if (torus.quadrant_axis >= 0) {
    const int k = torus.quadrant_axis, s = torus.quadrant_sign;
    const bool ok1 = wrap_detail::dsign(a1[k]) == s, ok2 = wrap_detail::dsign(a2[k]) == s;
    if (ok1 && ok2) best = distance(a1) < distance(a2) ? a1 : a2;
    else if (ok1) best = a1;
    else if (ok2) best = a2;
    else return {};  // no wrap on the constrained side
  } else {
    best = distance(a1) < distance(a2) ? a1 : a2;
  }
  const double rho = best->head<2>().norm();
  if (rho == 0) return {};  // the line runs along the torus's axis: no closest point
  const Eigen::Vector3d c(best->x() * R / rho, best->y() * R / rho, 0.0);
  // The cylinder's frame: x towards the torus's centre, y = -z of the torus, z = x cross y (the
  // circle's tangent). Its +x side is the inside of the ring.
  Eigen::Matrix3d axes;  // rows: the cylinder's axes in W
  axes.row(0) = -c / R;
  axes.row(1) = Eigen::Vector3d(0, 0, -1);
  axes.row(2) = Eigen::Vector3d(axes.row(0)).cross(Eigen::Vector3d(axes.row(1)));
  WrapObject cylinder;
  cylinder.shape = WrapObject::Shape::kCylinder;
  cylinder.radius_m = torus.inner_radius_m;
  cylinder.length_m = 10000.0;  // OpenSim's CYL_LENGTH
  cylinder.quadrant_axis = 0;
  cylinder.quadrant_sign = 1;
  SegmentWrap<double> w = wrap_cylinder<double>(cylinder, axes * (p1 - c), axes * (p2 - c));
  if (w.wraps()) {
    w.r1 = axes.transpose() * w.r1 + c;
    w.r2 = axes.transpose() * w.r2 + c;
  }
  return w;
}

}  // namespace cpgait
