#include "cpgait/muscles/smooth_segmented_function.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace cpgait {
namespace {

double bezier(const std::array<double, 6>& p, double u) {
  const double v = 1.0 - u, u2 = u * u, v2 = v * v;
  return v2 * v2 * v * p[0] + 5 * v2 * v2 * u * p[1] + 10 * v2 * v * u2 * p[2] + 10 * v2 * u2 * u * p[3] +
         5 * v * u2 * u2 * p[4] + u2 * u2 * u * p[5];
}

double bezier_du(const std::array<double, 6>& p, double u) {
  const double v = 1.0 - u, u2 = u * u, v2 = v * v;
  return 5 * (v2 * v2 * (p[1] - p[0]) + 4 * v2 * v * u * (p[2] - p[1]) + 6 * v2 * u2 * (p[3] - p[2]) +
              4 * v * u2 * u * (p[4] - p[3]) + u2 * u2 * (p[5] - p[4]));
}

}  // namespace

QuinticBezier quintic_bezier_corner(double x0, double y0, double dydx0, double x1, double y1, double dydx1,
                                    double curviness) {
  if (!(curviness >= 0 && curviness <= 1)) throw std::invalid_argument("curviness must be between 0 and 1");
  // The corner: where the two slopes' lines meet (their middle when they are parallel).
  const double xc = std::abs(dydx0 - dydx1) > std::sqrt(std::numeric_limits<double>::epsilon())
                        ? (y1 - y0 - x1 * dydx1 + x0 * dydx0) / (dydx0 - dydx1)
                        : 0.5 * (x1 + x0);
  const double yc = (xc - x1) * dydx1 + y1;
  const double a = (xc - x0) * (xc - x0) + (yc - y0) * (yc - y0);
  const double b = (xc - x1) * (xc - x1) + (yc - y1) * (yc - y1);
  const double c = (x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0);
  if (!(c > a && c > b))
    throw std::invalid_argument("the lines through the end points do not meet in a C-shaped corner");
  QuinticBezier s;
  s.x = {x0, x0 + curviness * (xc - x0), 0, 0, 0, x1};
  s.y = {y0, y0 + curviness * (yc - y0), 0, 0, 0, y1};
  s.x[2] = s.x[1];
  s.y[2] = s.y[1];
  s.x[3] = x1 + curviness * (xc - x1);
  s.y[3] = y1 + curviness * (yc - y1);
  s.x[4] = s.x[3];
  s.y[4] = s.y[3];
  return s;
}

SmoothSegmentedFunction::SmoothSegmentedFunction(std::vector<QuinticBezier> segments, double x0, double x1,
                                                 double y0, double y1, double dydx0, double dydx1)
    : segments_(std::move(segments)), x0_(x0), x1_(x1), y0_(y0), y1_(y1), dydx0_(dydx0), dydx1_(dydx1) {
  for (const auto& seg : segments_) {
    std::array<Node, kTable + 1> t{};
    for (int k = 0; k <= kTable; ++k) {
      const double x = seg.x[0] + (seg.x[5] - seg.x[0]) * k / kTable;
      double lo = 0, hi = 1;  // x(u) rises on a corner: bisection to machine precision
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (bezier(seg.x, mid) < x ? lo : hi) = mid;
      }
      const double u = 0.5 * (lo + hi), dx = bezier_du(seg.x, u);
      t[k] = {u, dx > 0 ? 1.0 / dx : 0.0};
    }
    u_table_.push_back(t);
  }
}

void SmoothSegmentedFunction::locate(double x, int& segment, double& u) const {
  // As OpenSim's calcIndex: the first segment with x0 <= x < x5, the last one at its very end.
  const int n = static_cast<int>(segments_.size());
  segment = n - 1;
  for (int i = 0; i < n; ++i)
    if (x >= segments_[i].x[0] && x < segments_[i].x[5]) {
      segment = i;
      break;
    }
  const auto& px = segments_[segment].x;
  const double width = px[5] - px[0];
  const double s = width > 0 ? std::clamp((x - px[0]) / width, 0.0, 1.0) * kTable : 0.0;
  const int k = std::min(static_cast<int>(s), kTable - 1);
  const Node& a = u_table_[segment][k];
  const Node& b = u_table_[segment][k + 1];
  // Cubic Hermite between the two nodes, in t in [0, 1] over a node spacing of width / kTable.
  const double t = s - k, h = width / kTable, t2 = t * t, t3 = t2 * t;
  u = (2 * t3 - 3 * t2 + 1) * a.u + (t3 - 2 * t2 + t) * h * a.du_dx + (-2 * t3 + 3 * t2) * b.u + (t3 - t2) * h * b.du_dx;
  // From the interpolated start (|x(u) - x| ~1e-9) one Newton step lands within rounding of the root:
  // the error squares. Otherwise Newton to OpenSim's 100 machine epsilons in x, with bisection where
  // Newton would leave the bracket.
  const double tol = 100 * std::numeric_limits<double>::epsilon();
  const double f0 = bezier(px, u) - x;
  if (std::abs(f0) <= 1e-7 * width) {
    u = std::clamp(u - f0 / bezier_du(px, u), 0.0, 1.0);
    return;
  }
  double lo = 0, hi = 1;
  for (int it = 0; it < 60; ++it) {
    const double f = bezier(px, u) - x;
    if (std::abs(f) <= tol) return;
    (f > 0 ? hi : lo) = u;
    const double df = bezier_du(px, u);
    double next = df != 0 ? u - f / df : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (next == u || hi - lo <= std::numeric_limits<double>::epsilon()) return;
    u = next;
  }
}

double SmoothSegmentedFunction::value(double x) const {
  if (x < x0_) return y0_ + dydx0_ * (x - x0_);
  if (x > x1_) return y1_ + dydx1_ * (x - x1_);
  int i;
  double u;
  locate(x, i, u);
  return bezier(segments_[i].y, u);
}

void SmoothSegmentedFunction::value_and_derivative(double x, double& y, double& dydx) const {
  if (x < x0_ || x > x1_) {
    y = value(x);
    dydx = derivative(x);
    return;
  }
  int i;
  double u;
  locate(x, i, u);
  y = bezier(segments_[i].y, u);
  dydx = bezier_du(segments_[i].y, u) / bezier_du(segments_[i].x, u);
}

double SmoothSegmentedFunction::derivative(double x) const {
  if (x < x0_) return dydx0_;
  if (x > x1_) return dydx1_;
  int i;
  double u;
  locate(x, i, u);
  return bezier_du(segments_[i].y, u) / bezier_du(segments_[i].x, u);
}

}  // namespace cpgait
