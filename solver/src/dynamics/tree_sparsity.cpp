#include "cpgait/dynamics/tree_sparsity.h"

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

BranchPattern::BranchPattern(std::vector<int> parent_of) : parent(std::move(parent_of)) {
  const int n = size();
  tree = true;
  for (int i = 0; i < n; ++i) tree = tree && parent[i] < i && parent[i] >= -1;
  if (!tree) return;
  std::vector<char> related(static_cast<std::size_t>(n) * n, 0);
  offset.assign(1, 0);
  for (int i = 0; i < n; ++i) {
    for (int j = i; j >= 0; j = parent[j]) {
      chain.push_back(j);
      related[i + static_cast<std::size_t>(j) * n] = 1;
    }
    offset.push_back(static_cast<int>(chain.size()));
  }
  for (int j = 0; j < n; ++j)
    for (int i = j + 1; i < n; ++i)
      if (!related[i + static_cast<std::size_t>(j) * n]) outside.emplace_back(i, j);
}

bool BranchPattern::holds(const Eigen::MatrixXd& A, bool both_triangles) const {
  if (!tree || A.rows() != size() || A.cols() != size()) return false;
  for (const auto& [i, j] : outside)
    if (A(i, j) != 0 || (both_triangles && A(j, i) != 0)) return false;
  return true;
}

}  // namespace cpgait
