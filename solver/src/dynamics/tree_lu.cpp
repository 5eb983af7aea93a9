#include "cpgait/dynamics/tree_lu.h"

namespace cpgait {

TreeLU::TreeLU(std::vector<int> parent) : pattern_(std::move(parent)) {
  lower_.resize(pattern_.chain.size());
  upper_.resize(pattern_.chain.size());
}

void TreeLU::compute(const Eigen::MatrixXd& A) {
  const int n = size();
  sparse_ = pattern_.holds(A, true);
  if (!sparse_) {
    dense_.compute(A);
    return;
  }
  const std::vector<int>& offset = pattern_.offset;
  for (int i = 0; i < n; ++i)
    for (int t = offset[i]; t < offset[i + 1]; ++t) {
      lower_[t] = A(i, pattern_.chain[t]);
      upper_[t] = A(pattern_.chain[t], i);
    }
  for (int k = n - 1; k >= 0; --k) {
    double* row = &lower_[offset[k]];
    const double* column = &upper_[offset[k]];
    const int* chain = &pattern_.chain[offset[k]];
    const int len = offset[k + 1] - offset[k];
    const double pivot = row[0];
    if (!(pivot > 0)) {  // the symmetric part is not definite: pivot rows
      sparse_ = false;
      dense_.compute(A);
      return;
    }
    for (int t = 1; t < len; ++t) row[t] /= pivot;
    // A(i, j) -= A(i, k) A(k, j) / A(k, k) over k's ancestors i, j: with i = chain[a] and j = chain[b]
    // (b >= a, so j is i or an ancestor of i), A(i, j) is row i's entry b - a and A(j, i) column i's.
    for (int a = 1; a < len; ++a) {
      double* row_i = &lower_[offset[chain[a]]];
      double* column_i = &upper_[offset[chain[a]]];
      const double from_column = column[a], from_row = row[a];
      row_i[0] -= from_column * from_row;
      for (int b = a + 1; b < len; ++b) {
        row_i[b - a] -= from_column * row[b];
        column_i[b - a] -= column[b] * from_row;
      }
    }
  }
}

}  // namespace cpgait
