#pragma once
// OpenSim's one-variable functions (Constant, LinearFunction, SimmSpline - also read for NaturalCubicSpline,
// PiecewiseLinearFunction, PolynomialFunction, MultiplierFunction folded in as `scale`), evaluated
// on any scalar type so that Ceres Jets differentiate through them exactly.
#include <string>
#include <vector>

#include "cpgait/scalar.h"

namespace cpgait {

class Function {
 public:
  enum class Kind { kConstant, kLinear, kCubicSpline, kPiecewiseLinear, kPolynomial };

  static Function constant(double value);
  static Function linear(double slope, double intercept);
  // Forsythe-Malcolm-Moler cubic spline with end third derivatives from divided differences
  // (OpenSim's SimmSpline); linear extrapolation with the end slopes.
  static Function simm_spline(std::vector<double> x, std::vector<double> y);
  static Function piecewise_linear(std::vector<double> x, std::vector<double> y);
  // coefficients from the highest power down, as OpenSim's PolynomialFunction.
  static Function polynomial(std::vector<double> coefficients);

  Function scaled(double factor) const;  // MultiplierFunction

  Kind kind() const { return kind_; }
  bool is_constant() const { return kind_ == Kind::kConstant; }
  // f(q) = q: a coordinate that is the translation itself (scaling leaves it alone).
  bool is_identity() const { return kind_ == Kind::kLinear && value(0.0) == 0.0 && value(1.0) == 1.0; }
  double scale() const { return scale_; }

  // Constant and linear functions (most of a joint's transform axes, evaluated in every pose) inline;
  // polynomials and splines out of line.
  template <typename T>
  T value(const T& x) const {
    if (kind_ == Kind::kConstant) return T(scale_ * c_[0]);
    if (kind_ == Kind::kLinear) return scale_ * (c_[0] * x + c_[1]);
    return curve_value(x);
  }
  template <typename T>
  T derivative(const T& x) const {
    if (kind_ == Kind::kConstant) return T(0.0);
    if (kind_ == Kind::kLinear) return T(scale_ * c_[0]);
    return curve_derivative(x);
  }
  double second_derivative(double x) const {
    return kind_ == Kind::kConstant || kind_ == Kind::kLinear ? 0.0 : curve_second_derivative(x);
  }

 private:
  Kind kind_ = Kind::kConstant;
  double scale_ = 1.0;
  // Constant: c_[0]. Linear: c_[0] slope, c_[1] intercept. Polynomial: c_ highest power first.
  std::vector<double> c_;
  // Splines: knots x_, values y_, and per-interval coefficients b_, cc_, d_ of
  // y_i + b_i dx + cc_i dx^2 + d_i dx^3.
  std::vector<double> x_, y_, b_, cc_, d_;
  // interval()'s index: the knots' span cut into even buckets (twice as many as intervals), each
  // with the interval its left edge lies in, so a lookup starts at most a few knots off (a sampled
  // trajectory's by bisection were a twentieth of CMC's instructions, a knee spline's 3 %).
  double buckets_per_x_ = 0;
  std::vector<int> bucket_interval_;
  void index_knots();
  template <typename T>
  T curve_value(const T& x) const;
  template <typename T>
  T curve_derivative(const T& x) const;
  double curve_second_derivative(double x) const;
  int interval(double x) const;
};

template <typename T>
T Function::curve_value(const T& x) const {
  switch (kind_) {
    case Kind::kConstant:
    case Kind::kLinear:
      break;  // value() has them
    case Kind::kPolynomial: {
      T r(0.0);
      for (double c : c_) r = r * x + c;
      return scale_ * r;
    }
    case Kind::kPiecewiseLinear:
    case Kind::kCubicSpline: {
      const double xv = scalar_value(x);
      const int n = static_cast<int>(x_.size());
      if (xv < x_[0]) return scale_ * (y_[0] + b_[0] * (x - x_[0]));
      if (xv > x_[n - 1]) return scale_ * (y_[n - 1] + b_[n - 1] * (x - x_[n - 1]));
      const int i = interval(xv);
      const T dx = x - x_[i];
      return scale_ * (y_[i] + dx * (b_[i] + dx * (cc_[i] + dx * d_[i])));
    }
  }
  return T(0.0);
}

template <typename T>
T Function::curve_derivative(const T& x) const {
  switch (kind_) {
    case Kind::kConstant:
    case Kind::kLinear:
      break;  // derivative() has them
    case Kind::kPolynomial: {
      T r(0.0);
      const int deg = static_cast<int>(c_.size()) - 1;
      for (int k = 0; k < deg; ++k) r = r * x + c_[k] * (deg - k);
      return scale_ * r;
    }
    case Kind::kPiecewiseLinear:
    case Kind::kCubicSpline: {
      const double xv = scalar_value(x);
      const int n = static_cast<int>(x_.size());
      if (xv < x_[0]) return T(scale_ * b_[0]);
      if (xv > x_[n - 1]) return T(scale_ * b_[n - 1]);
      const int i = interval(xv);
      const T dx = x - x_[i];
      return scale_ * (b_[i] + dx * (2.0 * cc_[i] + 3.0 * d_[i] * dx));
    }
  }
  return T(0.0);
}

}  // namespace cpgait
