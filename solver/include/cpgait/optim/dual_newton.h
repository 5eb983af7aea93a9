#pragma once
// min sum_i |x_i|^p  subject to  A x = b,  lo <= x <= hi   (p >= 2)
//
// The core is a separable quadratic program, min sum_i (h_i/2) y_i^2 + g_i y_i with the same kind
// of constraints, solved by Newton's method on its Lagrangian dual: for multipliers lambda each y_i
// is a clamped linear function of (A^T lambda)_i, the dual is concave with a piecewise-linear
// gradient b - A y(lambda) and generalized Hessian -A D A^T (D = 1/h on the free variables). Each
// step solves one m x m system (m = rows of A: 23 coordinates against ~100 actuators in static
// optimization) and the iteration ends, exactly, once the active set is right: a handful of steps.
// Along each step the dual is piecewise quadratic: the line search halves from the full step, or
// starts at the dual's exact maximiser along it where that comes first (exact_line_search).
// p = 2 is that quadratic program itself; other exponents take sequential quadratic steps from
// the p = 2 solution, each a feasible descent step with a backtracking line search. Below p = 2
// the curvature of |x|^p is unbounded at zero and these steps stall, so p < 2 is refused.
#include <Eigen/Core>

namespace cpgait {

struct DualNewtonOptions {
  double exponent = 2.0;
  double tolerance = 1e-10;   // on |A x - b|_inf, relative to 1 + |b|_inf
  int max_iterations = 200;   // dual Newton steps per quadratic program
  int max_outer_iterations = 50;  // sequential quadratic steps when exponent != 2
  // Start each line search at the dual's maximiser along the step (found by walking its breakpoints)
  // where it lies short of the full step: pays where warm starts cross many bounds, as CMC's windows
  // do (measured in DualNewton.WarmStartedSequenceTakesFewSteps). Default false.
  bool exact_line_search = false;
};

struct DualNewtonSummary {
  int iterations = 0;            // dual Newton steps, all quadratic programs together
  int line_search_evaluations = 0;  // of the dual, over those steps' line searches
  int outer_iterations = 0;      // sequential quadratic steps (0 for p = 2)
  double equality_residual = 0;  // |A x - b|_inf at the end
  bool converged = false;
};

// min sum (h_i/2) y_i^2 + g_i y_i, A y = b, lo <= y <= hi (h > 0). lambda: warm start in (empty:
// cold start from the solution without bounds), multipliers out.
DualNewtonSummary minimize_separable_quadratic(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                                               const Eigen::VectorXd& h, const Eigen::VectorXd& g,
                                               const Eigen::VectorXd& lo, const Eigen::VectorXd& hi,
                                               const DualNewtonOptions& options, Eigen::VectorXd& lambda,
                                               Eigen::VectorXd& y);

// lambda as above (for p = 2 they are the problem's multipliers); x: solution out.
DualNewtonSummary minimize_power_sum(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& lo,
                                     const Eigen::VectorXd& hi, const DualNewtonOptions& options, Eigen::VectorXd& lambda,
                                     Eigen::VectorXd& x);

}  // namespace cpgait
