#pragma once
// The value part of a scalar that may be a Ceres Jet: branches (spline intervals, conditional path
// points) are taken on the value so that derivatives stay exact within a branch.
#include <type_traits>

namespace cpgait {

template <typename T>
double scalar_value(const T& x) {
  if constexpr (std::is_arithmetic_v<T>) {
    return static_cast<double>(x);
  } else {
    return scalar_value(x.a);  // ceres::Jet, possibly nested (hyper-dual numbers)
  }
}

}  // namespace cpgait
