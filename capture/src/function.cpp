#include "cpgait/capture/function.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cpgait {

Function Function::constant(double value) {
  Function f;
  f.kind_ = Kind::kConstant;
  f.c_ = {value};
  return f;
}

Function Function::linear(double slope, double intercept) {
  Function f;
  f.kind_ = Kind::kLinear;
  f.c_ = {slope, intercept};
  return f;
}

Function Function::polynomial(std::vector<double> coefficients) {
  if (coefficients.empty()) return constant(0.0);
  Function f;
  f.kind_ = Kind::kPolynomial;
  f.c_ = std::move(coefficients);
  return f;
}

static void check_knots(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) throw std::invalid_argument("spline x and y have different lengths");
  if (x.size() < 2) throw std::invalid_argument("spline needs at least 2 points");
  for (std::size_t i = 1; i < x.size(); ++i)
    if (!(x[i] > x[i - 1])) throw std::invalid_argument("spline x values must increase");
}

Function Function::piecewise_linear(std::vector<double> x, std::vector<double> y) {
  check_knots(x, y);
  Function f;
  f.kind_ = Kind::kPiecewiseLinear;
  const std::size_t n = x.size();
  f.b_.assign(n, 0.0);
  f.cc_.assign(n, 0.0);
  f.d_.assign(n, 0.0);
  for (std::size_t i = 0; i + 1 < n; ++i) f.b_[i] = (y[i + 1] - y[i]) / (x[i + 1] - x[i]);
  f.b_[n - 1] = f.b_[n - 2];
  f.x_ = std::move(x);
  f.y_ = std::move(y);
  f.index_knots();
  return f;
}

// Forsythe, Malcolm & Moler, "Computer Methods for Mathematical Computations" (1977), SPLINE.
Function Function::simm_spline(std::vector<double> x, std::vector<double> y) {
  check_knots(x, y);
  const int n = static_cast<int>(x.size());
  if (n < 3) return piecewise_linear(std::move(x), std::move(y));
  Function f;
  f.kind_ = Kind::kCubicSpline;
  std::vector<double> b(n), c(n), d(n);
  const int nm1 = n - 1;
  // Tridiagonal system: b diagonal, d off-diagonal, c right-hand side.
  d[0] = x[1] - x[0];
  c[1] = (y[1] - y[0]) / d[0];
  for (int i = 1; i < nm1; ++i) {
    d[i] = x[i + 1] - x[i];
    b[i] = 2.0 * (d[i - 1] + d[i]);
    c[i + 1] = (y[i + 1] - y[i]) / d[i];
    c[i] = c[i + 1] - c[i];
  }
  // End conditions: third derivatives at the ends match those of cubics through the end 4 points.
  b[0] = -d[0];
  b[nm1] = -d[n - 2];
  c[0] = 0.0;
  c[nm1] = 0.0;
  if (n > 3) {
    c[0] = c[2] / (x[3] - x[1]) - c[1] / (x[2] - x[0]);
    c[nm1] = c[n - 2] / (x[nm1] - x[n - 3]) - c[n - 3] / (x[n - 2] - x[n - 4]);
    c[0] = c[0] * d[0] * d[0] / (x[3] - x[0]);
    c[nm1] = -c[nm1] * d[n - 2] * d[n - 2] / (x[nm1] - x[n - 4]);
  }
  for (int i = 1; i < n; ++i) {
    const double t = d[i - 1] / b[i - 1];
    b[i] -= t * d[i - 1];
    c[i] -= t * c[i - 1];
  }
  c[nm1] /= b[nm1];
  for (int i = n - 2; i >= 0; --i) c[i] = (c[i] - d[i] * c[i + 1]) / b[i];
  b[nm1] = (y[nm1] - y[n - 2]) / d[n - 2] + d[n - 2] * (c[n - 2] + 2.0 * c[nm1]);
  for (int i = 0; i < nm1; ++i) {
    b[i] = (y[i + 1] - y[i]) / d[i] - d[i] * (c[i + 1] + 2.0 * c[i]);
    d[i] = (c[i + 1] - c[i]) / d[i];
    c[i] *= 3.0;
  }
  c[nm1] *= 3.0;
  d[nm1] = d[n - 2];
  f.x_ = std::move(x);
  f.y_ = std::move(y);
  f.b_ = std::move(b);
  f.cc_ = std::move(c);
  f.d_ = std::move(d);
  f.index_knots();
  return f;
}

Function Function::scaled(double factor) const {
  Function f = *this;
  f.scale_ *= factor;
  return f;
}

void Function::index_knots() {
  const int n = static_cast<int>(x_.size());
  if (n < 2 || !(x_.back() > x_.front())) return;
  const int buckets = 2 * (n - 1);
  buckets_per_x_ = buckets / (x_.back() - x_.front());
  bucket_interval_.resize(static_cast<std::size_t>(buckets));
  for (int b = 0, i = 0; b < buckets; ++b) {
    const double left = x_.front() + b / buckets_per_x_;
    while (i < n - 2 && x_[i + 1] <= left) ++i;
    bucket_interval_[static_cast<std::size_t>(b)] = i;
  }
}

int Function::interval(double x) const {
  // x_[i] <= x < x_[i+1]; the last knot belongs to the last interval. The bucket's interval is a
  // start: rounding in the bucket's index may land it a knot off either way, and a bucket may hold
  // several knots.
  const int last = static_cast<int>(x_.size()) - 2;
  if (buckets_per_x_ > 0 && x >= x_.front() && x <= x_.back()) {
    const int b = std::clamp(static_cast<int>((x - x_.front()) * buckets_per_x_), 0, static_cast<int>(bucket_interval_.size()) - 1);
    int i = bucket_interval_[static_cast<std::size_t>(b)];
    while (i > 0 && x_[i] > x) --i;
    while (i < last && x_[i + 1] <= x) ++i;
    return i;
  }
  auto it = std::upper_bound(x_.begin(), x_.end(), x);
  int i = static_cast<int>(it - x_.begin()) - 1;
  return std::clamp(i, 0, last);
}

double Function::curve_second_derivative(double x) const {
  switch (kind_) {
    case Kind::kConstant:
    case Kind::kLinear:
      return 0.0;
    case Kind::kPolynomial: {
      double r = 0.0;
      const int deg = static_cast<int>(c_.size()) - 1;
      for (int k = 0; k < deg - 1; ++k) r = r * x + c_[k] * (deg - k) * (deg - k - 1);
      return scale_ * r;
    }
    case Kind::kPiecewiseLinear:
    case Kind::kCubicSpline: {
      const int n = static_cast<int>(x_.size());
      if (x < x_[0] || x > x_[n - 1]) return 0.0;
      const int i = interval(x);
      return scale_ * (2.0 * cc_[i] + 6.0 * (x - x_[i]) * d_[i]);
    }
  }
  return 0.0;
}

}  // namespace cpgait
