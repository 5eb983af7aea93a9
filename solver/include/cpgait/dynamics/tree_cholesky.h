#pragma once
// Featherstone's LTL factorization (Rigid Body Dynamics Algorithms, 2008, section 6.5): A = L^T L
// with L lower triangular and nonzero only where the column's coordinate is the row's own or an
// ancestor's in the kinematic tree (branch-induced sparsity). A joint-space mass matrix has that
// pattern, so does M plus damping and stiffness that couple only coordinates on one branch (muscles
// spanning a chain of joints, a foot's contact on its leg). On gait2392's 23 coordinates: 778
// multiply-adds against a dense Cholesky's 2,024. A matrix with any nonzero outside the pattern, or
// a tree whose parents do not precede their children, is factored densely instead (Eigen's LLT):
// the solution is the same either way.
#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "cpgait/dynamics/tree_sparsity.h"

namespace cpgait {

class TreeCholesky {
 public:
  TreeCholesky() = default;
  // parent[i] < i, or -1; an order where a parent follows its child factors densely.
  explicit TreeCholesky(std::vector<int> parent);

  // Success() false if A is not positive definite.
  void compute(const Eigen::MatrixXd& A);
  bool success() const { return ok_; }
  int size() const { return pattern_.size(); }
  // Whether the last compute used the tree's sparsity (for tests).
  bool sparse() const { return sparse_; }

  template <typename Derived>
  void solve_in_place(Eigen::MatrixBase<Derived>& x) const {
    if (!sparse_) {
      dense_.solveInPlace(x);
      return;
    }
    const int n = size();
    const std::vector<int>& offset = pattern_.offset;
    for (Eigen::Index col = 0; col < x.cols(); ++col) {
      // L^T y = b, leaves first; then L x = y, root first.
      for (int i = n - 1; i >= 0; --i) {
        const double* row = &values_[offset[i]];
        const int* chain = &pattern_.chain[offset[i]];
        const double xi = x(i, col) /= row[0];
        for (int t = 1; t < offset[i + 1] - offset[i]; ++t) x(chain[t], col) -= row[t] * xi;
      }
      for (int i = 0; i < n; ++i) {
        const double* row = &values_[offset[i]];
        const int* chain = &pattern_.chain[offset[i]];
        double xi = x(i, col);
        for (int t = 1; t < offset[i + 1] - offset[i]; ++t) xi -= row[t] * x(chain[t], col);
        x(i, col) = xi / row[0];
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
  // Row i of L over its chain: values_[offset[i] + t] is L(i, chain[offset[i] + t]). A row's
  // ancestors' chains are suffixes of its own, so the updates run along contiguous rows.
  std::vector<double> values_;
  bool sparse_ = false, ok_ = false;
  Eigen::LLT<Eigen::MatrixXd> dense_;
};

}  // namespace cpgait
