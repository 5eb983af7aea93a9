#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "cpgait/capture/function.h"

using namespace cpgait;

namespace {
const std::vector<double> kX = {-2.0944, -1.74533, -1.39626, -1.0472, -0.698132, -0.349066, -0.174533, 0.197344, 0.337395, 0.490178, 1.52146, 2.0944};
const std::vector<double> kY = {-0.0032, 0.00179, 0.00411, 0.0041, 0.00212, -0.001, -0.0031, -0.005227, -0.005435, -0.005574, -0.005435, -0.00525};

void expect_derivatives_consistent(const Function& f, double lo, double hi) {
  for (int i = 0; i <= 200; ++i) {
    const double x = lo + (hi - lo) * i / 200.0 + 1e-7;  // off the knots
    const double h = 1e-6;
    EXPECT_NEAR(f.derivative(x), (f.value(x + h) - f.value(x - h)) / (2 * h), 1e-6) << "at x=" << x;
    EXPECT_NEAR(f.second_derivative(x), (f.derivative(x + h) - f.derivative(x - h)) / (2 * h), 1e-4) << "at x=" << x;
    ceres::Jet<double, 1> j(x, 0);
    EXPECT_NEAR(f.value(j).v[0], f.derivative(x), 1e-12);
  }
}
}  // namespace

TEST(Function, SimmSplineInterpolatesKnotsAndIsSmooth) {
  const Function f = Function::simm_spline(kX, kY);
  for (std::size_t i = 0; i < kX.size(); ++i) EXPECT_NEAR(f.value(kX[i]), kY[i], 1e-14);
  expect_derivatives_consistent(f, -2.0, 2.0);
  // Continuous first and second derivatives across an inner knot.
  const double k = kX[5], e = 1e-9;
  EXPECT_NEAR(f.derivative(k - e), f.derivative(k + e), 1e-6);
  EXPECT_NEAR(f.second_derivative(k - e), f.second_derivative(k + e), 1e-5);
}

TEST(Function, SimmSplineReproducesACubicExactly) {
  // FMM's end conditions match the third derivative of cubics through the end points, so a cubic
  // is reproduced exactly: a check that distinguishes it from a natural spline.
  std::vector<double> x, y;
  for (int i = 0; i < 7; ++i) {
    x.push_back(i * 0.3 + (i % 2) * 0.05);
    y.push_back(0.5 * std::pow(x.back(), 3) - x.back() + 2);
  }
  const Function f = Function::simm_spline(x, y);
  for (double t = 0.0; t < 1.8; t += 0.01) EXPECT_NEAR(f.value(t), 0.5 * t * t * t - t + 2, 1e-12);
}

TEST(Function, LinearExtrapolationOutsideTheKnots) {
  const Function f = Function::simm_spline(kX, kY);
  const double slope = f.derivative(kX.back());
  EXPECT_NEAR(f.value(kX.back() + 0.5), kY.back() + 0.5 * slope, 1e-12);
  EXPECT_NEAR(f.derivative(-3.0), f.derivative(kX.front()), 1e-12);
}

TEST(Function, LinearPolynomialConstantAndMultiplier) {
  EXPECT_DOUBLE_EQ(Function::linear(2, 1).value(3.0), 7.0);
  EXPECT_DOUBLE_EQ(Function::constant(4).derivative(1.0), 0.0);
  const Function p = Function::polynomial({1, 0, -2, 3});  // x^3 - 2x + 3
  EXPECT_DOUBLE_EQ(p.value(2.0), 7.0);
  EXPECT_DOUBLE_EQ(p.derivative(2.0), 10.0);
  EXPECT_DOUBLE_EQ(p.second_derivative(2.0), 12.0);
  const Function s = Function::simm_spline(kX, kY).scaled(1.14724);
  EXPECT_NEAR(s.value(kX[3]), 1.14724 * kY[3], 1e-14);
  expect_derivatives_consistent(s, -1.5, 1.5);
  EXPECT_THROW(Function::simm_spline({0, 0, 1}, {1, 2, 3}), std::invalid_argument);
}

// Sampled trajectories have evenly spaced knots, where the interval is guessed from the spacing
// rather than bisected: every lookup must find bisection's interval (a wrong one extrapolates a
// neighbour's segment). Checked on a piecewise-linear function, whose value is exactly
// y_i + (x - x_i) slope_i, at, just below and between the knots; on times rounded as .sto files
// round them; and on uneven knots, which keep bisection.
// Lookups start from an index of even buckets: evenly spaced knots (a trajectory), uneven ones, and
// clusters of knots within one bucket beside long gaps (as a knee spline's) land on bisection's interval.
TEST(Function, KnotsFindTheirIntervals) {
  std::vector<double> even, uneven, clustered, y;
  for (int i = 0; i < 300; ++i) {
    even.push_back(std::round((0.5 + i / 120.0) * 1e7) / 1e7);  // 120 Hz, 7 decimals
    uneven.push_back(i + 0.002 * i * i);
    clustered.push_back(i % 50 < 45 ? 100.0 * (i / 50) + 1e-3 * (i % 50) : 100.0 * (i / 50) + 19.0 * (i % 50 - 44));
    y.push_back(std::sin(0.37 * i) + 0.1 * i);
  }
  for (const auto& x : {even, uneven, clustered}) {
    const Function f = Function::piecewise_linear(x, y);
    auto expected = [&](double t) {
      const int n = static_cast<int>(x.size());
      const int i = std::clamp(static_cast<int>(std::upper_bound(x.begin(), x.end(), t) - x.begin()) - 1, 0, n - 2);
      return y[i] + (t - x[i]) * ((y[i + 1] - y[i]) / (x[i + 1] - x[i]));
    };
    for (std::size_t i = 0; i < x.size(); ++i) {
      for (double t : {x[i], std::nextafter(x[i], -1e9), i + 1 < x.size() ? 0.5 * (x[i] + x[i + 1]) : x[i]}) {
        if (t < x.front()) continue;
        EXPECT_EQ(f.value(t), expected(t)) << "t = " << t << " near knot " << i;
      }
    }
  }
}
