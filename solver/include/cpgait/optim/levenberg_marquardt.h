#pragma once
// min (1/2) |r(x)|^2 subject to lo <= x <= hi, for small dense problems solved many times in a row
// (inverse kinematics: ~120 residuals, ~23 unknowns, a solve per frame): Levenberg-Marquardt with
// Ceres' trust-region strategy (Moré's scaling by diag(J^T J); the radius grows after good steps and
// shrinks by 2, 4, 8... after rejected ones), variables held on the bounds their gradient pushes
// against, and steps projected onto the bounds. Without Ceres' per-solve set-up it runs IK about
// 1.5x faster. Nothing is allocated per solve once the workspace has its sizes.
#include <Eigen/Core>
#include <functional>

namespace cpgait {

struct LevenbergMarquardtOptions {
  int max_iterations = 200;
  double function_tolerance = 1e-9;    // converged when a step changes (or the model predicts the next to change) the cost by less than this fraction
  double gradient_tolerance = 1e-14;   // ... or the projected gradient's max-norm is below this
  double parameter_tolerance = 1e-10;  // ... or a step is shorter than this times (|x| + this)
  double initial_radius = 1e4;         // trust region (Ceres' default); 1/radius weighs diag(J^T J)
};

struct LevenbergMarquardtSummary {
  int iterations = 0;  // steps tried (each a residual and Jacobian evaluation)
  bool converged = false;
  double initial_cost = 0, final_cost = 0;  // (1/2) |r|^2
};

// r = f(x); when J is not null also the Jacobian, row-major (residuals x unknowns).
using ResidualFunction = std::function<void(const double* x, double* r, double* J)>;

struct LevenbergMarquardtWorkspace {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J, J_new;
  Eigen::MatrixXd H, A;
  Eigen::VectorXd r, r_new, g, rhs, d, x_new, step;
};

// x: start in (projected onto the bounds), solution out. lo/hi may hold -inf/+inf.
LevenbergMarquardtSummary levenberg_marquardt(const ResidualFunction& f, int num_residuals, const Eigen::VectorXd& lo,
                                              const Eigen::VectorXd& hi, const LevenbergMarquardtOptions& options,
                                              Eigen::VectorXd& x, LevenbergMarquardtWorkspace& workspace);

}  // namespace cpgait
