#pragma once
// Branch-induced sparsity (Featherstone, Rigid Body Dynamics Algorithms, 2008, section 6.5): in the
// tree's order (parents before children) a joint-space mass matrix is nonzero only where one
// coordinate is the other or an ancestor of it, and factoring it leaves first fills nothing in.
// The pattern TreeCholesky and TreeLU factor on.
#include <Eigen/Core>
#include <utility>
#include <vector>

#include "cpgait/model/model.h"

namespace cpgait {

// Each coordinate's parent in the branch-induced order: the joint's previous coordinate, else the
// last coordinate of the nearest ancestor joint that has any; -1 at the root.
std::vector<int> coordinate_parents(const Model& model);

struct BranchPattern {
  BranchPattern() = default;
  // parent[i] < i, or -1; an order where a parent follows its child has no pattern (tree false).
  explicit BranchPattern(std::vector<int> parent);
  int size() const { return static_cast<int>(parent.size()); }
  // Whether A is size x size and zero outside the pattern: its lower triangle (a symmetric A), or
  // both triangles.
  bool holds(const Eigen::MatrixXd& A, bool both_triangles) const;

  std::vector<int> parent;
  // Coordinate i's chain (i, its parent, ..., the root) is chain[offset[i] .. offset[i + 1]); an
  // ancestor's chain is a suffix of its descendant's.
  std::vector<int> offset, chain;
  std::vector<std::pair<int, int>> outside;  // the lower triangle's entries (i > j) outside the pattern
  bool tree = false;
};

}  // namespace cpgait
