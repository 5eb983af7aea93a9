#include "cpgait/cpg/cpg_phase.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cpgait {

int cpg_rhythm_neurons(const MatsuokaNetwork& n) {
  const int N = n.size();
  for (int r = 1; r < N; ++r)
    if (n.a.topRightCorner(r, N - r).isZero(0.0)) return r;
  return N;
}

CpgPhaseTable cpg_phase_table(const CpgModel& m, int samples) {
  if (samples < 8) throw std::invalid_argument("cpg_phase_table: at least 8 samples");
  CpgPhaseTable t;
  t.rhythm_neurons = cpg_rhythm_neurons(m.network);
  t.phase_at_start = m.phase_at_start;
  const int R = t.rhythm_neurons, substeps = 10;
  t.states.resize(samples, 2 * R);
  // The network in seconds at speed 1: its period is the gait cycle. The rhythm neurons alone:
  // no later neuron inhibits them, so the pattern layer cannot change their course.
  MatsuokaNetwork rhythm;
  rhythm.tau_r_s = m.network.tau_r_s.head(R);
  rhythm.tau_a_s = m.network.tau_a_s.head(R);
  rhythm.b = m.network.b.head(R);
  rhythm.s = m.network.s.head(R);
  rhythm.a = m.network.a.topLeftCorner(R, R);
  MatsuokaState st{m.start.x.head(R), m.start.f.head(R)};
  MatsuokaScratch scratch;
  matsuoka_prepare(rhythm, scratch);
  const Eigen::VectorXd none;
  const double dt = m.cycle_s / (samples * substeps);
  for (int k = 0; k < samples; ++k) {
    t.states.row(k) << st.x.transpose(), st.f.transpose();
    for (int i = 0; i < substeps; ++i) matsuoka_step(rhythm, st, dt, none, scratch);
  }
  const Eigen::VectorXd range = t.states.colwise().maxCoeff() - t.states.colwise().minCoeff();
  t.inv_range = range.unaryExpr([](double r) { return r > 1e-12 ? 1.0 / r : 0.0; });
  t.states = t.states * t.inv_range.asDiagonal();
  return t;
}

namespace {

Eigen::RowVectorXd scaled_state(const CpgPhaseTable& t, const MatsuokaState& state) {
  const int R = t.rhythm_neurons;
  Eigen::RowVectorXd s(2 * R);
  s << state.x.head(R).transpose(), state.f.head(R).transpose();
  return s.cwiseProduct(t.inv_range.transpose());
}

// Sample k's squared distance to s, summed over the coordinates in order (as the vectorized sums
// over all samples add them, so both give the same value).
double squared_distance(const CpgPhaseTable& t, const Eigen::RowVectorXd& s, Eigen::Index k) {
  double sum = 0;
  for (Eigen::Index j = 0; j < s.size(); ++j) {
    const double e = t.states(k, j) - s[j];
    sum += e * e;
  }
  return sum;
}

// The nearest sample (the first, where several are): the squared distance to every sample, summed
// column by column (vectorized across the samples; each sum in squared_distance's order).
Eigen::Index nearest_sample(const CpgPhaseTable& t, const Eigen::RowVectorXd& s) {
  Eigen::VectorXd d2 = Eigen::VectorXd::Zero(t.states.rows());
  for (Eigen::Index j = 0; j < s.size(); ++j) d2.array() += (t.states.col(j).array() - s[j]).square();
  Eigen::Index k = 0;
  d2.minCoeff(&k);
  return k;
}

// The phase from the nearest sample k, refined along the segment to its nearer neighbour.
double phase_near(const CpgPhaseTable& t, const Eigen::RowVectorXd& s, Eigen::Index k) {
  const Eigen::Index S = t.states.rows();
  const Eigen::Index prev = (k + S - 1) % S, next = (k + 1) % S;
  const bool forward = squared_distance(t, s, next) <= squared_distance(t, s, prev);
  const Eigen::Index a = forward ? k : prev, b = forward ? next : k;
  const Eigen::RowVectorXd seg = t.states.row(b) - t.states.row(a);
  const double len2 = seg.squaredNorm();
  const double frac = len2 > 0 ? std::clamp((s - t.states.row(a)).dot(seg) / len2, 0.0, 1.0) : 0.0;
  const double phase = t.phase_at_start + (static_cast<double>(a) + frac) / S;
  return phase - std::floor(phase);
}

}  // namespace

double cpg_phase(const CpgPhaseTable& t, const MatsuokaState& state) {
  const Eigen::RowVectorXd s = scaled_state(t, state);
  return phase_near(t, s, nearest_sample(t, s));
}

double cpg_phase(const CpgPhaseTable& t, const MatsuokaState& state, int& nearest) {
  const Eigen::Index S = t.states.rows(), n = t.states.cols();
  const Eigen::RowVectorXd s = scaled_state(t, state);
  if (nearest < 0 || nearest >= S) {
    const Eigen::Index k = nearest_sample(t, s);
    nearest = static_cast<int>(k);
    return phase_near(t, s, k);
  }
  Eigen::Index best = nearest;
  double best_d2 = squared_distance(t, s, best);
  // Each partial sum is squared_distance's and adding squares never lowers it, so a sample dropped
  // once its partial sum exceeds the best is farther than the best; the first minimum in index order
  // is nearest_sample's.
  for (Eigen::Index k = 0; k < S; ++k) {
    double sum = 0;
    Eigen::Index j = 0;
    for (; j < n && sum <= best_d2; ++j) {
      const double e = t.states(k, j) - s[j];
      sum += e * e;
    }
    if (sum < best_d2 || (sum == best_d2 && j == n && k < best)) best_d2 = sum, best = k;
  }
  nearest = static_cast<int>(best);
  return phase_near(t, s, best);
}

}  // namespace cpgait
