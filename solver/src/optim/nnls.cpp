#include "cpgait/optim/nnls.h"

#include <Eigen/Cholesky>
#include <limits>
#include <map>
#include <vector>

namespace cpgait {

Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, int max_iterations) {
  return nnls_columns(A, b, max_iterations).col(0);
}

Eigen::MatrixXd nnls_columns(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, int max_iterations) {
  const Eigen::Index n = A.cols();
  if (max_iterations <= 0) max_iterations = 3 * static_cast<int>(n) + 10;
  // On the normal equations: A's Gram matrix is n x n, so each column's steps cost O(n^2) however
  // many rows A has (the CPG's designs: a few neurons, a hundred phases, every muscle). The passive
  // set as a key (variables in order) and its factorisation, made once.
  const Eigen::MatrixXd G = A.transpose() * A;
  const Eigen::MatrixXd C = A.transpose() * B;
  std::map<std::vector<bool>, Eigen::LDLT<Eigen::MatrixXd>> factorisations;
  const double a_max = A.cwiseAbs().maxCoeff();
  Eigen::MatrixXd X(n, B.cols());
  std::vector<Eigen::Index> idx;
  Eigen::VectorXd cp, zp, w(n);
  std::vector<bool> passive;  // the set P of free (positive) variables
  for (Eigen::Index col = 0; col < B.cols(); ++col) {
    const auto c = C.col(col);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    passive.assign(static_cast<std::size_t>(n), false);
    const double tol = 1e-12 * (1.0 + a_max) * (1.0 + B.col(col).cwiseAbs().maxCoeff());
    auto solve_passive = [&](Eigen::VectorXd& z) {
      idx.clear();
      for (Eigen::Index j = 0; j < n; ++j)
        if (passive[static_cast<std::size_t>(j)]) idx.push_back(j);
      const Eigen::Index k = static_cast<Eigen::Index>(idx.size());
      auto it = factorisations.find(passive);
      if (it == factorisations.end()) {
        Eigen::MatrixXd Gp(k, k);
        for (Eigen::Index i = 0; i < k; ++i)
          for (Eigen::Index j = 0; j < k; ++j) Gp(i, j) = G(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(j)]);
        it = factorisations.emplace(passive, Gp.ldlt()).first;
      }
      cp.resize(k);
      for (Eigen::Index i = 0; i < k; ++i) cp[i] = c[idx[static_cast<std::size_t>(i)]];
      zp = it->second.solve(cp);
      z.setZero(n);
      for (Eigen::Index i = 0; i < k; ++i) z[idx[static_cast<std::size_t>(i)]] = zp[i];
    };
    Eigen::VectorXd z(n);
    for (int outer = 0; outer < max_iterations; ++outer) {
      w = c;
      w.noalias() -= G * x;  // negative gradient, A^T (b - A x)
      Eigen::Index best = -1;
      double best_w = tol;
      for (Eigen::Index j = 0; j < n; ++j)
        if (!passive[static_cast<std::size_t>(j)] && w[j] > best_w) best_w = w[j], best = j;
      if (best < 0) break;  // KKT: no variable at zero wants to grow
      passive[static_cast<std::size_t>(best)] = true;
      for (int inner = 0; inner < max_iterations; ++inner) {
        solve_passive(z);
        bool feasible = true;
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<std::size_t>(j)] && z[j] <= 0) feasible = false;
        if (feasible) break;
        // Step from x toward z as far as feasibility allows; variables reaching zero leave P.
        double alpha = std::numeric_limits<double>::infinity();
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<std::size_t>(j)] && z[j] <= 0) alpha = std::min(alpha, x[j] / (x[j] - z[j]));
        x += alpha * (z - x);
        for (Eigen::Index j = 0; j < n; ++j)
          if (passive[static_cast<std::size_t>(j)] && x[j] <= 1e-15) passive[static_cast<std::size_t>(j)] = false, x[j] = 0;
      }
      x = z;
    }
    X.col(col) = x;
  }
  return X;
}

}  // namespace cpgait
