#include "cpgait/dynamics/tree_cholesky.h"

#include <cmath>

namespace cpgait {

std::vector<int> coordinate_parents(const Model& model) {
  std::vector<int> parent(model.num_coordinates(), -1);
  std::vector<int> last(model.bodies.size(), -1);  // the last coordinate moving each body
  for (const Joint& j : model.joints) {  // parents come first
    int previous = j.parent_body >= 0 ? last[j.parent_body] : -1;
    for (int c : j.coordinates) {
      parent[c] = previous;
      previous = c;
    }
    last[j.child_body] = previous;
  }
  return parent;
}

TreeCholesky::TreeCholesky(std::vector<int> parent) : parent_(std::move(parent)) {
  const int n = static_cast<int>(parent_.size());
  tree_ = true;
  for (int i = 0; i < n; ++i) tree_ = tree_ && parent_[i] < i && parent_[i] >= -1;
  if (!tree_) return;
  std::vector<char> related(static_cast<std::size_t>(n) * n, 0);
  offset_.assign(1, 0);
  for (int i = 0; i < n; ++i) {
    for (int j = i; j >= 0; j = parent_[j]) {
      chain_.push_back(j);
      related[i + static_cast<std::size_t>(j) * n] = 1;
    }
    offset_.push_back(static_cast<int>(chain_.size()));
  }
  for (int j = 0; j < n; ++j)
    for (int i = j + 1; i < n; ++i)
      if (!related[i + static_cast<std::size_t>(j) * n]) outside_.emplace_back(i, j);
  values_.resize(chain_.size());
}

void TreeCholesky::compute(const Eigen::MatrixXd& A) {
  const int n = size();
  sparse_ = tree_ && A.rows() == n && A.cols() == n;
  for (std::size_t e = 0; sparse_ && e < outside_.size(); ++e) sparse_ = A(outside_[e].first, outside_[e].second) == 0;
  if (!sparse_) {
    dense_.compute(A);
    ok_ = dense_.info() == Eigen::Success;
    return;
  }
  for (int i = 0; i < n; ++i)
    for (int t = offset_[i]; t < offset_[i + 1]; ++t) values_[t] = A(i, chain_[t]);
  ok_ = true;
  for (int k = n - 1; k >= 0; --k) {
    double* row = &values_[offset_[k]];
    const int* chain = &chain_[offset_[k]];
    const int len = offset_[k + 1] - offset_[k];
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
      double* row_i = &values_[offset_[chain[a]]];
      const double f = row[a];
      for (int b = a; b < len; ++b) row_i[b - a] -= f * row[b];
    }
  }
}

}  // namespace cpgait
