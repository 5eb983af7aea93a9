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

double cpg_phase(const CpgPhaseTable& t, const MatsuokaState& state) {
  const int R = t.rhythm_neurons, S = static_cast<int>(t.states.rows());
  Eigen::RowVectorXd s(2 * R);
  s << state.x.head(R).transpose(), state.f.head(R).transpose();
  s = s.cwiseProduct(t.inv_range.transpose());
  // The squared distance to every sample, summed column by column (vectorized across the samples;
  // each sum in a row's squaredNorm order, so that the nearest is the one it always was).
  Eigen::VectorXd d2 = Eigen::VectorXd::Zero(S);
  for (Eigen::Index j = 0; j < s.size(); ++j) d2.array() += (t.states.col(j).array() - s[j]).square();
  Eigen::Index k = 0;
  d2.minCoeff(&k);
  // Along the segment to the nearer neighbour: the projection's fraction.
  const Eigen::Index prev = (k + S - 1) % S, next = (k + 1) % S;
  const bool forward = d2[next] <= d2[prev];
  const Eigen::Index a = forward ? k : prev, b = forward ? next : k;
  const Eigen::RowVectorXd seg = t.states.row(b) - t.states.row(a);
  const double len2 = seg.squaredNorm();
  const double frac = len2 > 0 ? std::clamp((s - t.states.row(a)).dot(seg) / len2, 0.0, 1.0) : 0.0;
  const double phase = t.phase_at_start + (static_cast<double>(a) + frac) / S;
  return phase - std::floor(phase);
}

}  // namespace cpgait
