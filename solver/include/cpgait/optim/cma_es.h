#pragma once
// Derivative-free minimisation of f(x), x in R^n, by the Covariance Matrix Adaptation Evolution
// Strategy (Hansen, "The CMA Evolution Strategy: A Tutorial", arXiv:1604.00772, 2016): each
// generation samples lambda points from N(m, sigma^2 C), moves m to the weighted mean of the best
// mu, and adapts C (rank-one and rank-mu updates) and sigma (cumulative step-size adaptation). For
// objectives that are simulations (noisy, discontinuous where a model falls): the candidates of a
// generation are evaluated in parallel.
#include <Eigen/Core>
#include <functional>
#include <string>

namespace cpgait {

struct CmaEsOptions {
  double initial_sigma = 0.3;     // initial step size, in the units of x (default 0.3)
  int population = 0;             // lambda, at least 2 (it recombines the better half); 0: 4 + floor(3 ln n), the tutorial's default
  int max_evaluations = 10000;    // stop after this many evaluations of f (default 10,000)
  double target_value = -1e300;   // stop once f(best) <= this (default: never)
  double function_tolerance = 1e-12;  // stop when a generation's and the last 10 generations' best values span less than this
  double x_tolerance = 1e-12;     // stop when sigma * sqrt(max diag C) is below this
  // Box bounds (empty: none). A candidate outside is evaluated at its projection, plus a penalty of
  // its squared distance times bound_penalty (per unit^2, default 1e3 * the first generation's f
  // spread); the unprojected sample drives the update, as in Hansen's boundary handling.
  Eigen::VectorXd lower, upper;
  double bound_penalty = 0;       // 0: chosen from the first generation as above
  int num_threads = 0;            // evaluations in parallel; 0: every core
  unsigned long long seed = 1;    // the same seed gives the same search, whatever num_threads
};

struct CmaEsSummary {
  Eigen::VectorXd best_x;         // the best point evaluated (projected onto the bounds)
  double best_value = 0;
  int evaluations = 0, generations = 0;
  double final_sigma = 0;
  std::string termination;        // which rule stopped the search
  double seconds = 0;
  std::string BriefReport() const;
};

// f must be safe to call from several threads at once.
using CmaEsObjective = std::function<double(const Eigen::VectorXd& x)>;

CmaEsSummary cma_es(const CmaEsObjective& f, const Eigen::VectorXd& x0, const CmaEsOptions& options = {});

}  // namespace cpgait
