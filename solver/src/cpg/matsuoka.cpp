#include "cpgait/cpg/matsuoka.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cpgait {

MatsuokaNetwork MatsuokaNetwork::pair(double s, double tau_r_s, double tau_a_s, double b, double a12, double a21) {
  MatsuokaNetwork n;
  n.tau_r_s = Eigen::Vector2d::Constant(tau_r_s);
  n.tau_a_s = Eigen::Vector2d::Constant(tau_a_s);
  n.b = Eigen::Vector2d::Constant(b);
  n.s = Eigen::Vector2d::Constant(s);
  n.a = Eigen::Matrix2d::Zero();
  n.a(0, 1) = a12;
  n.a(1, 0) = a21;
  return n;
}

MatsuokaState MatsuokaState::resting(const MatsuokaNetwork& n) {
  MatsuokaState st;
  st.x = Eigen::VectorXd::Zero(n.size());
  st.f = Eigen::VectorXd::Zero(n.size());
  for (int i = 0; i < n.size(); ++i) st.x[i] = 0.1 * (i % 2 == 0 ? 1.0 : -1.0) + 0.01 * i;
  return st;
}

void matsuoka_rates(const MatsuokaNetwork& n, const MatsuokaState& st, const Eigen::VectorXd& u, MatsuokaState& r,
                    const Eigen::SparseMatrix<double>* sparse_a) {
  // Written so that the inner loop of fitting allocates nothing: the outputs y = max(x, 0) go through
  // r.f, the inhibition a y through r.x (one vectorized matrix-vector product, column by column).
  const Eigen::Index N = n.s.size();
  r.x.resize(N);
  r.f.resize(N);
  r.f = st.x.cwiseMax(0.0);
  if (sparse_a) {
    // Column by column as Eigen's sparse product runs, skipping the silent neurons (y = 0): half of
    // them at any time, and their zero products leave every sum as it was.
    r.x.setZero();
    for (Eigen::Index j = 0; j < N; ++j) {
      const double y = r.f[j];
      if (y == 0.0) continue;
      for (Eigen::SparseMatrix<double>::InnerIterator it(*sparse_a, j); it; ++it) r.x[it.index()] += it.value() * y;
    }
  } else {
    r.x.noalias() = n.a * r.f;
  }
  // Whole-vector (SIMD) arithmetic: in the reproduced gait this runs four times per millisecond.
  if (u.size() == N)
    r.x = (n.s - st.x - n.b.cwiseProduct(st.f) - r.x + u).cwiseQuotient(n.tau_r_s);
  else
    r.x = (n.s - st.x - n.b.cwiseProduct(st.f) - r.x).cwiseQuotient(n.tau_r_s);
  r.f = (r.f - st.f).cwiseQuotient(n.tau_a_s);
}

void matsuoka_prepare(const MatsuokaNetwork& n, MatsuokaScratch& w) { w.a = n.a.sparseView(); }

void matsuoka_step(const MatsuokaNetwork& n, MatsuokaState& st, double dt, const Eigen::VectorXd& u, MatsuokaScratch& w) {
  const Eigen::SparseMatrix<double>* a = w.a.rows() == n.size() ? &w.a : nullptr;
  matsuoka_rates(n, st, u, w.k1, a);
  w.tmp.x.resize(st.x.size());
  w.tmp.f.resize(st.f.size());
  w.tmp.x = st.x + 0.5 * dt * w.k1.x;
  w.tmp.f = st.f + 0.5 * dt * w.k1.f;
  matsuoka_rates(n, w.tmp, u, w.k2, a);
  w.tmp.x = st.x + 0.5 * dt * w.k2.x;
  w.tmp.f = st.f + 0.5 * dt * w.k2.f;
  matsuoka_rates(n, w.tmp, u, w.k3, a);
  w.tmp.x = st.x + dt * w.k3.x;
  w.tmp.f = st.f + dt * w.k3.f;
  matsuoka_rates(n, w.tmp, u, w.k4, a);
  st.x += dt / 6.0 * (w.k1.x + 2 * w.k2.x + 2 * w.k3.x + w.k4.x);
  st.f += dt / 6.0 * (w.k1.f + 2 * w.k2.f + 2 * w.k3.f + w.k4.f);
}

Eigen::MatrixXd simulate_matsuoka(const MatsuokaNetwork& n, MatsuokaState& st, double dt, int steps, const Eigen::MatrixXd& input) {
  Eigen::MatrixXd out(steps, n.size());
  MatsuokaScratch w;
  if (steps > 1) matsuoka_prepare(n, w);
  Eigen::VectorXd u;
  for (int i = 0; i < steps; ++i) {
    if (input.rows() > i) u = input.row(i).transpose();
    matsuoka_step(n, st, dt, u, w);
    out.row(i) = st.x.cwiseMax(0.0).transpose();
  }
  return out;
}

double matsuoka_natural_frequency(double tr, double ta, double b, double a) {
  const double arg = ((tr + ta) * b - tr * a) / (tr * a);
  return arg > 0 ? std::sqrt(arg) / ta : 0.0;
}

double oscillation_period(const Eigen::VectorXd& y, double dt, int skip) {
  const Eigen::VectorXd tail = y.tail(y.size() - skip);
  if (tail.size() < 3) return 0;
  const double mean = tail.mean();
  std::vector<double> crossings;
  for (Eigen::Index i = 1; i < tail.size(); ++i)
    if (tail[i - 1] < mean && tail[i] >= mean)
      crossings.push_back((i - 1 + (mean - tail[i - 1]) / (tail[i] - tail[i - 1])) * dt);
  if (crossings.size() < 3) return 0;
  return (crossings.back() - crossings.front()) / (crossings.size() - 1);
}

}  // namespace cpgait
