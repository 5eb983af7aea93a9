#include "cpgait/dynamics/tree_cholesky.h"

#include <cmath>

namespace cpgait {

TreeCholesky::TreeCholesky(std::vector<int> parent) : pattern_(std::move(parent)) { values_.resize(pattern_.chain.size()); }

void TreeCholesky::compute(const Eigen::MatrixXd& A) {
  const int n = size();
  sparse_ = pattern_.holds(A, false);
  if (!sparse_) {
    dense_.compute(A);
    ok_ = dense_.info() == Eigen::Success;
    return;
  }
  const std::vector<int>& offset = pattern_.offset;
  for (int i = 0; i < n; ++i)
    for (int t = offset[i]; t < offset[i + 1]; ++t) values_[t] = A(i, pattern_.chain[t]);
  ok_ = true;
  for (int k = n - 1; k >= 0; --k) {
    double* row = &values_[offset[k]];
    const int* chain = &pattern_.chain[offset[k]];
    const int len = offset[k + 1] - offset[k];
    if (!(row[0] > 0)) {  // not positive definite: as Eigen's LLT reports it
      sparse_ = false;
      dense_.compute(A);
      ok_ = false;
      return;
    }
    row[0] = std::sqrt(row[0]);
    for (int t = 1; t < len; ++t) row[t] /= row[0];
    // L(i, j) -= L(k, i) L(k, j) for i an ancestor of k and j one of i (or i): row i's chain is the
    // suffix of k's from i on.
    for (int a = 1; a < len; ++a) {
      double* row_i = &values_[offset[chain[a]]];
      const double f = row[a];
      for (int b = a; b < len; ++b) row_i[b - a] -= f * row[b];
    }
  }
}

}  // namespace cpgait
