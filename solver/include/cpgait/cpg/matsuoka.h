#pragma once
// Matsuoka's neural oscillator network (Matsuoka 1985):
//   Tr_i dx_i/dt = -x_i + s_i - b_i f_i - sum_j a_ij y_j + u_i     y_i = max(0, x_i)
//   Ta_i df_i/dt = -f_i + y_i
// x: membrane state, f: self-inhibition (adaptation), s: tonic input, a: inhibition weights,
// u: external input (feedback). Integrated with classical Runge-Kutta at a fixed step: the right
// side is only piecewise linear, so a fixed step that resolves Tr is accurate and reproducible.
#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace cpgait {

struct MatsuokaNetwork {
  Eigen::VectorXd tau_r_s, tau_a_s, b, s;
  Eigen::MatrixXd a;  // a(i, j): how strongly neuron j's output inhibits neuron i; zero diagonal
  int size() const { return static_cast<int>(s.size()); }
  // The classic mutually inhibiting pair.
  static MatsuokaNetwork pair(double s, double tau_r_s, double tau_a_s, double b, double a12, double a21);
};

struct MatsuokaState {
  Eigen::VectorXd x, f;
  static MatsuokaState resting(const MatsuokaNetwork& n);  // small asymmetric start, so pairs swing
};

// dx/dt and df/dt at a state, with external input u (empty: none); rates must not be state itself.
// sparse_a: n.a as a sparse matrix (matsuoka_prepare), or nullptr to use n.a.
void matsuoka_rates(const MatsuokaNetwork& n, const MatsuokaState& state, const Eigen::VectorXd& u, MatsuokaState& rates,
                    const Eigen::SparseMatrix<double>* sparse_a = nullptr);

// One classical Runge-Kutta step in place; `scratch` holds the stages (sized on first use).
struct MatsuokaScratch {
  MatsuokaState k1, k2, k3, k4, tmp;
  Eigen::SparseMatrix<double> a;  // set by matsuoka_prepare; empty: steps use the network's dense a
};
// For a network stepped many times unchanged: its inhibition kept sparse in the scratch (fitted
// networks are ~2 % non-zero: 708 of 178 x 178 weights on subject01), which later steps use. Call it
// again whenever the network's a changes.
void matsuoka_prepare(const MatsuokaNetwork& n, MatsuokaScratch& scratch);
void matsuoka_step(const MatsuokaNetwork& n, MatsuokaState& state, double dt_s, const Eigen::VectorXd& u, MatsuokaScratch& scratch);

// Advances `state` by `steps` steps of dt; returns outputs y (steps x neurons) after each step.
// input (steps x neurons) is the external input per step, or empty.
Eigen::MatrixXd simulate_matsuoka(const MatsuokaNetwork& n, MatsuokaState& state, double dt_s, int steps,
                                  const Eigen::MatrixXd& input = Eigen::MatrixXd());

// Matsuoka's (2011) estimate of a symmetric pair's oscillation frequency (rad/s), from the
// describing function of the half-wave output: w = (1/Ta) sqrt(((Tr + Ta) b - Tr a) / (Tr a)).
double matsuoka_natural_frequency(double tau_r_s, double tau_a_s, double b, double a);

// Mean period of a periodic signal (s): time between upward crossings of its mean, after
// discarding the first `skip` samples (transient). 0 when it does not oscillate.
double oscillation_period(const Eigen::VectorXd& signal, double dt_s, int skip = 0);

}  // namespace cpgait
