#pragma once
// TreeCholesky's unsymmetric counterpart: A = U L by Gaussian elimination leaves first (the tree's
// order reversed) without pivoting, U upper and L unit lower triangular, both on the branch pattern
// (tree_sparsity.h), so nothing fills in. For a matrix whose symmetric part is positive definite -
// a mass matrix plus a step's unsymmetric damping and stiffness - every pivot is positive and the
// elimination stays stable while the skew part is small beside the symmetric one (Golub & Van Loan,
// Matrix Computations, 4.2, unsymmetric positive definite systems). A pivot that is not positive, a
// nonzero outside the pattern in either triangle, or a parent after its child: factored densely
// instead (Eigen's PartialPivLU); the solution is the same either way.
#include <Eigen/Core>
#include <Eigen/LU>
#include <vector>

#include "cpgait/dynamics/tree_sparsity.h"

namespace cpgait {

class TreeLU {
 public:
  TreeLU() = default;
  explicit TreeLU(std::vector<int> parent);

  void compute(const Eigen::MatrixXd& A);
  int size() const { return pattern_.size(); }
  // Whether the last compute used the tree's sparsity (for tests).
  bool sparse() const { return sparse_; }

  template <typename Derived>
  void solve_in_place(Eigen::MatrixBase<Derived>& x) const {
    if (!sparse_) {
      const typename Derived::PlainObject b = x;
      x = dense_.solve(b);
      return;
    }
    const int n = size();
    const std::vector<int>& offset = pattern_.offset;
    for (Eigen::Index col = 0; col < x.cols(); ++col) {
      // U y = b, leaves first (U's column k reaches k's ancestors); then L x = y, root first.
      for (int k = n - 1; k >= 0; --k) {
        const double* column = &upper_[offset[k]];
        const int* chain = &pattern_.chain[offset[k]];
        const double yk = x(k, col) /= lower_[offset[k]];
        for (int t = 1; t < offset[k + 1] - offset[k]; ++t) x(chain[t], col) -= column[t] * yk;
      }
      for (int k = 0; k < n; ++k) {
        const double* row = &lower_[offset[k]];
        const int* chain = &pattern_.chain[offset[k]];
        double xk = x(k, col);
        for (int t = 1; t < offset[k + 1] - offset[k]; ++t) xk -= row[t] * x(chain[t], col);
        x(k, col) = xk;
      }
    }
  }
  template <typename Rhs>
  typename Rhs::PlainObject solve(const Eigen::MatrixBase<Rhs>& b) const {
    typename Rhs::PlainObject x = b;
    solve_in_place(x);
    return x;
  }

 private:
  BranchPattern pattern_;
  // Over coordinate k's chain: lower_[offset[k]] is U(k, k) and lower_[offset[k] + t] is
  // L(k, chain[offset[k] + t]); upper_[offset[k] + t] is U(chain[offset[k] + t], k) (t >= 1).
  std::vector<double> lower_, upper_;
  bool sparse_ = false;
  Eigen::PartialPivLU<Eigen::MatrixXd> dense_;
};

}  // namespace cpgait
