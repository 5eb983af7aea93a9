#pragma once
// Non-negative least squares, min |A x - b| subject to x >= 0, by Lawson and Hanson's active-set
// algorithm ("Solving Least Squares Problems", 1974, chapter 23). Exact in finitely many steps.
#include <Eigen/Core>

namespace cpgait {

// Returns x (A.cols()); max_iterations bounds the outer loop (3 n by default).
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, int max_iterations = 0);

}  // namespace cpgait
