#include "cpgait/muscles/smooth_segmented_function.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace cpgait {
namespace {

// Bernstein control points -> power-basis coefficients c (p(u) = sum c_k u^k).
std::array<double, 6> power_basis(const std::array<double, 6>& p) {
  return {p[0],
          5 * (p[1] - p[0]),
          10 * (p[2] - 2 * p[1] + p[0]),
          10 * (p[3] - 3 * p[2] + 3 * p[1] - p[0]),
          5 * (p[4] - 4 * p[3] + 6 * p[2] - 4 * p[1] + p[0]),
          p[5] - 5 * p[4] + 10 * p[3] - 10 * p[2] + 5 * p[1] - p[0]};
}

double horner(const std::array<double, 6>& c, double u) {
  return ((((c[5] * u + c[4]) * u + c[3]) * u + c[2]) * u + c[1]) * u + c[0];
}

// The derivative's power-basis coefficients.
std::array<double, 5> derivative_coefficients(const std::array<double, 6>& c) { return {c[1], 2 * c[2], 3 * c[3], 4 * c[4], 5 * c[5]}; }

double horner(const std::array<double, 5>& c, double u) { return (((c[4] * u + c[3]) * u + c[2]) * u + c[1]) * u + c[0]; }

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
    const double width = seg.x[5] - seg.x[0];
    const std::array<double, 6> px = power_basis(seg.x), py = power_basis(seg.y);
    const std::array<double, 5> dpx = derivative_coefficients(px);
    polynomials_.push_back({px, py, dpx, derivative_coefficients(py), seg.x[0], seg.x[5], width, width > 0 ? kTable / width : 0.0});
    struct Node {
      double u, du_dx;
    };
    std::array<Node, kTable + 1> t{};
    double u = 0;
    for (int k = 0; k <= kTable; ++k) {
      // x(u) rises on a corner: Newton from the previous node, within the bracket [previous u, 1],
      // bisecting where a step would leave it, to machine precision.
      const double x = seg.x[0] + width * k / kTable;
      double lo = u, hi = 1;
      for (int it = 0; it < 100 && hi - lo > 0; ++it) {
        const double f = horner(px, u) - x;
        if (f == 0) break;
        (f > 0 ? hi : lo) = u;
        const double df = horner(dpx, u);
        double next = df > 0 ? u - f / df : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        if (next == u) break;
        u = next;
      }
      const double dx = horner(dpx, u);
      t[k] = {u, dx > 0 ? 1.0 / dx : 0.0};
    }
    // The cubic Hermite between nodes k and k + 1 (node spacing h) in powers of t.
    std::array<std::array<double, 4>, kTable> cubic{};
    const double h = width / kTable;
    for (int k = 0; k < kTable; ++k) {
      const double u0 = t[k].u, u1 = t[k + 1].u, m0 = h * t[k].du_dx, m1 = h * t[k + 1].du_dx;
      cubic[k] = {u0, m0, -3 * u0 - 2 * m0 + 3 * u1 - m1, 2 * u0 + m0 - 2 * u1 + m1};
    }
    u_table_.push_back(cubic);
  }
}

// Inlined into every lookup (a CMC makes millions): the table start and one Newton step. The rare
// start further out goes on in refine().
inline void SmoothSegmentedFunction::locate(double x, int& segment, double& u) const {
  // As OpenSim's calcIndex: the first segment with x0 <= x < x5, the last one at its very end.
  const int n = static_cast<int>(polynomials_.size());
  segment = n - 1;
  for (int i = 0; i < n; ++i)
    if (x >= polynomials_[i].x_begin && x < polynomials_[i].x_end) {
      segment = i;
      break;
    }
  const Polynomials& p = polynomials_[segment];
  if (std::isnan(x)) {  // NaN in, NaN out: the table index below would be undefined
    u = x;
    return;
  }
  const double s = std::clamp((x - p.x_begin) * p.nodes_per_x, 0.0, double(kTable));
  const int k = std::min(static_cast<int>(s), kTable - 1);
  const std::array<double, 4>& c = u_table_[segment][k];
  const double t = s - k;
  u = ((c[3] * t + c[2]) * t + c[1]) * t + c[0];
  // From the interpolated start (|x(u) - x| ~1e-9) one Newton step lands within rounding of the root:
  // the error squares.
  const double f0 = horner(p.x, u) - x;
  if (std::abs(f0) <= 1e-7 * p.width) {
    u = std::clamp(u - f0 / horner(p.dx, u), 0.0, 1.0);
    return;
  }
  refine(x, p, u);
}

void SmoothSegmentedFunction::refine(double x, const Polynomials& p, double& u) {
  // Newton to OpenSim's 100 machine epsilons in x, with bisection where Newton would leave the bracket.
  const double tol = 100 * std::numeric_limits<double>::epsilon();
  double lo = 0, hi = 1;
  for (int it = 0; it < 60; ++it) {
    const double f = horner(p.x, u) - x;
    if (std::abs(f) <= tol) return;
    (f > 0 ? hi : lo) = u;
    const double df = horner(p.dx, u);
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
  return horner(polynomials_[i].y, u);
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
  const Polynomials& p = polynomials_[i];
  y = horner(p.y, u);
  dydx = horner(p.dy, u) / horner(p.dx, u);
}

double SmoothSegmentedFunction::derivative(double x) const {
  if (x < x0_) return dydx0_;
  if (x > x1_) return dydx1_;
  int i;
  double u;
  locate(x, i, u);
  return horner(polynomials_[i].dy, u) / horner(polynomials_[i].dx, u);
}

}  // namespace cpgait
