#pragma once
// The pattern layer of a CPG: a muscle's own Matsuoka neurons driven by a periodic rhythm.
//   dx_i/dt = -x_i + s_i - b_i f_i - sum_j c_ij r_j(t)   (Tr = 1)
//   Ta df_i/dt = -f_i + y_i,   y_i = max(0, x_i)
// r(t): the rhythm neurons' outputs over one period, sampled at equal phases. The units do not inhibit
// each other: a lone unit driven by a periodic input settles on one periodic response, while a
// mutually inhibiting pair can oscillate on its own and drift from the rhythm (measured: fits that the
// running network did not reproduce). Fitting finds s, b, c and Ta so that a non-negative combination
// of the y_i (plus a bias) matches one muscle's pattern.
#include <Eigen/Core>

namespace cpgait {

struct PatternNeurons {
  int units = 0;
  double tau_a = 1;       // adaptation time constant / Tr
  Eigen::VectorXd s, b;   // per unit
  Eigen::MatrixXd c;      // units x rhythm neurons (signed)
  Eigen::VectorXd weights;  // output map (>= 0)
  double bias = 0;          // (>= 0)
  Eigen::VectorXd x0, f0;   // state at phase 0 of the steady cycle
  Eigen::MatrixXd outputs;  // steady cycle: fine phases x units
};

// `fine_rhythm`: fine phases x rhythm neurons over one period of `period` (in units of Tr), phase 0
// first; `target`: the muscle's pattern at `target.size()` equal phases (fine phases must be a
// multiple). The search integrates one step per target phase; the result is simulated at the fine
// phases. Returns the best of `starts` fits whose response to the rhythm is periodic; `fitted`
// receives the pattern it reproduces.
PatternNeurons fit_pattern_neurons(const Eigen::MatrixXd& fine_rhythm, double period, const Eigen::VectorXd& target, int units,
                                   int starts, unsigned seed, Eigen::VectorXd& fitted);

}  // namespace cpgait
