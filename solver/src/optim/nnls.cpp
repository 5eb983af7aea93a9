#include "cpgait/optim/nnls.h"

#include <Eigen/QR>
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
  // The passive set as a key (variables in order) and its factorisation, made once.
  std::map<std::vector<bool>, Eigen::ColPivHouseholderQR<Eigen::MatrixXd>> factorisations;
  const double a_max = A.cwiseAbs().maxCoeff();
  Eigen::MatrixXd X(n, B.cols());
  for (Eigen::Index col = 0; col < B.cols(); ++col) {
    const Eigen::VectorXd b = B.col(col);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    std::vector<bool> passive(static_cast<std::size_t>(n), false);  // the set P of free (positive) variables
    const double tol = 1e-12 * (1.0 + a_max) * (1.0 + b.cwiseAbs().maxCoeff());
    auto solve_passive = [&](Eigen::VectorXd& z) {
      std::vector<Eigen::Index> idx;
      for (Eigen::Index j = 0; j < n; ++j)
        if (passive[static_cast<std::size_t>(j)]) idx.push_back(j);
      auto it = factorisations.find(passive);
      if (it == factorisations.end()) {
        Eigen::MatrixXd Ap(A.rows(), static_cast<Eigen::Index>(idx.size()));
        for (std::size_t k = 0; k < idx.size(); ++k) Ap.col(static_cast<Eigen::Index>(k)) = A.col(idx[k]);
        it = factorisations.emplace(passive, Ap.colPivHouseholderQr()).first;
      }
      const Eigen::VectorXd zp = it->second.solve(b);
      z.setZero(n);
      for (std::size_t k = 0; k < idx.size(); ++k) z[idx[k]] = zp[static_cast<Eigen::Index>(k)];
    };
    Eigen::VectorXd z(n);
    for (int outer = 0; outer < max_iterations; ++outer) {
      const Eigen::VectorXd w = A.transpose() * (b - A * x);  // negative gradient
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
