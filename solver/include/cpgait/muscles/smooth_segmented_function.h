#pragma once
// OpenSim's SmoothSegmentedFunction: a C2-continuous curve made of quintic Bezier segments, each a
// "corner" between two points with given slopes, extended linearly beyond its ends. Millard's muscle
// curves are built from it (millard2012.h). y(x) is found by solving x(u) = x for the Bezier
// parameter u (Newton, safeguarded by bisection: x(u) rises monotonically on every corner).
#include <array>
#include <vector>

namespace cpgait {

struct QuinticBezier {
  std::array<double, 6> x, y;  // control points
};

// OpenSim's calcQuinticBezierCornerControlPoints: the segment from (x0, y0) with slope dydx0 to
// (x1, y1) with slope dydx1, bent towards the slopes' intersection by `curviness` in [0, 1].
// Throws std::invalid_argument where the two lines do not form a C-shaped corner.
QuinticBezier quintic_bezier_corner(double x0, double y0, double dydx0, double x1, double y1, double dydx1,
                                    double curviness);

class SmoothSegmentedFunction {
 public:
  SmoothSegmentedFunction() = default;
  // Segments in increasing x, each starting where the previous ends; outside [x0, x1] the curve
  // continues along the straight lines through (x0, y0) and (x1, y1) with slopes dydx0, dydx1.
  SmoothSegmentedFunction(std::vector<QuinticBezier> segments, double x0, double x1, double y0, double y1,
                          double dydx0, double dydx1);
  double value(double x) const;
  double derivative(double x) const;  // dy/dx
  void value_and_derivative(double x, double& y, double& dydx) const;  // one solve for both
  bool empty() const { return segments_.empty(); }
  double x_begin() const { return x0_; }
  double x_end() const { return x1_; }
  const std::vector<QuinticBezier>& segments() const { return segments_; }

 private:
  // Index of the segment holding x and its Bezier parameter u.
  void locate(double x, int& segment, double& u) const;
  std::vector<QuinticBezier> segments_;
  // Each segment's x(u) and y(u), and their derivatives, in the power basis (Horner: a fifth of the
  // Bernstein form's multiplications; a CMC evaluates them millions of times), its x range's start
  // and width, and kTable / width.
  struct Polynomials {
    std::array<double, 6> x, y;
    std::array<double, 5> dx, dy;  // dx/du and dy/du
    double x_begin, x_end, width, nodes_per_x;
  };
  std::vector<Polynomials> polynomials_;
  // locate()'s Newton from a start the table left further out.
  static void refine(double x, const Polynomials& p, double& u);
  // Per segment, u and du/dx at evenly spaced x: their cubic Hermite interpolant starts Newton within
  // 1e-7 of the segment's width on Millard's curves, and one step finishes (OpenSim starts from a
  // spline of u(x) too). At 32 nodes two thirds of a CMC's force-velocity lookups, near isometric,
  // started further out and iterated (measured). Kept per interval in the power basis of its
  // position t in [0, 1] (Horner: a third of the Hermite basis' operations).
  static constexpr int kTable = 256;
  std::vector<std::array<std::array<double, 4>, kTable>> u_table_;
  double x0_ = 0, x1_ = 0, y0_ = 0, y1_ = 0, dydx0_ = 0, dydx1_ = 0;
};

}  // namespace cpgait
