#pragma once
// Non-negative least squares, min |A x - b| subject to x >= 0, by Lawson and Hanson's active-set
// algorithm ("Solving Least Squares Problems", 1974, chapter 23). Exact in finitely many steps.
#include <Eigen/Core>

namespace cpgait {

// Returns x (A.cols()); max_iterations bounds the outer loop (3 n + 10 by default).
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, int max_iterations = 0);

// One x per column of B (A.cols() x B.cols()), as nnls() gives each. Solved on the normal equations
// (A^T A is n x n), with the factorisations of its passive subsets shared between the columns (the
// CPG's output map: a few neurons, a hundred phases, every muscle on one design).
Eigen::MatrixXd nnls_columns(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, int max_iterations = 0);

}  // namespace cpgait
