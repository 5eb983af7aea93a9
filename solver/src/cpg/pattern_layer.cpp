#include "cpgait/cpg/pattern_layer.h"

#include <ceres/ceres.h>

#include <cmath>
#include <random>

#include "cpgait/optim/nnls.h"

namespace cpgait {
namespace {

// Parameters: block 0 = [tau_a, mutual, then per unit: s, b, c_1..c_R]; block 1 = [weights..., bias].
struct Layout {
  int units, rhythm;
  int per_unit() const { return 2 + rhythm; }
  int size() const { return 2 + units * per_unit(); }
};

template <typename T>
T relu(const T& v) {
  return v > T(0) ? v : T(0);
}

// Simulates the units driven by the periodic rhythm (RK4 with the drive interpolated within a step)
// from (x, f), for `settle` periods and then one recorded period; (x, f) end at the recorded period's
// start state... returned in x0/f0. outputs: F x units of the recorded period.
template <typename T>
void simulate(const Layout& L, const T* p, const Eigen::MatrixXd& rhythm, double period, int settle, std::vector<T>& x,
              std::vector<T>& f, std::vector<T>& x0, std::vector<T>& f0, std::vector<T>& outputs) {
  const int F = static_cast<int>(rhythm.rows()), U = L.units, R = L.rhythm;
  const T dt = T(period / F);
  const T tau_a = p[0], mutual = p[1];
  std::vector<T> drive(static_cast<std::size_t>(F * U));
  for (int k = 0; k < F; ++k)
    for (int u = 0; u < U; ++u) {
      const T* q = p + 2 + u * L.per_unit();
      T d(0);
      for (int j = 0; j < R; ++j) d += q[2 + j] * rhythm(k, j);
      drive[static_cast<std::size_t>(k * U + u)] = d;
    }
  auto rates = [&](const T* xs, const T* fs, int k0, int k1, double w1, T* dx, T* df) {
    for (int u = 0; u < U; ++u) {
      const T* q = p + 2 + u * L.per_unit();
      const T d = (1.0 - w1) * drive[static_cast<std::size_t>(k0 * U + u)] + w1 * drive[static_cast<std::size_t>(k1 * U + u)];
      dx[u] = -xs[u] + q[0] - q[1] * fs[u] - d;
      if (U == 2) dx[u] -= mutual * relu(xs[1 - u]);
      df[u] = (relu(xs[u]) - fs[u]) / tau_a;
    }
  };
  T k1x[2], k1f[2], k2x[2], k2f[2], k3x[2], k3f[2], k4x[2], k4f[2], tx[2], tf[2];
  outputs.assign(static_cast<std::size_t>(F * U), T(0));
  for (int cycle = 0; cycle <= settle; ++cycle)
    for (int k = 0; k < F; ++k) {
      const bool record = cycle == settle;
      if (record && k == 0) x0 = x, f0 = f;
      if (record)
        for (int u = 0; u < U; ++u) outputs[static_cast<std::size_t>(k * U + u)] = relu(x[static_cast<std::size_t>(u)]);
      const int k1 = (k + 1) % F;
      rates(x.data(), f.data(), k, k1, 0.0, k1x, k1f);
      for (int u = 0; u < U; ++u) tx[u] = x[u] + 0.5 * dt * k1x[u], tf[u] = f[u] + 0.5 * dt * k1f[u];
      rates(tx, tf, k, k1, 0.5, k2x, k2f);
      for (int u = 0; u < U; ++u) tx[u] = x[u] + 0.5 * dt * k2x[u], tf[u] = f[u] + 0.5 * dt * k2f[u];
      rates(tx, tf, k, k1, 0.5, k3x, k3f);
      for (int u = 0; u < U; ++u) tx[u] = x[u] + dt * k3x[u], tf[u] = f[u] + dt * k3f[u];
      rates(tx, tf, k, k1, 1.0, k4x, k4f);
      for (int u = 0; u < U; ++u) {
        x[static_cast<std::size_t>(u)] += dt / 6.0 * (k1x[u] + 2.0 * k2x[u] + 2.0 * k3x[u] + k4x[u]);
        f[static_cast<std::size_t>(u)] += dt / 6.0 * (k1f[u] + 2.0 * k2f[u] + 2.0 * k3f[u] + k4f[u]);
      }
    }
}

// Periods to simulate before the recorded one: the slowest transient (Ta) decays to 1e-3.
int settle_periods(double tau_a, double period) { return 1 + static_cast<int>(std::ceil(7.0 * std::max(tau_a, 1.0) / period)); }

double value_of(double v) { return v; }
template <typename J>
double value_of(const J& v) {
  return v.a;
}

// The residual: target - (weights . outputs + bias) at the target's phases. The steady state of the
// previous evaluation starts the next (parameters change little between Ceres' evaluations), so one
// settling period suffices after the first call.
struct Residual {
  Layout layout;
  const Eigen::MatrixXd* rhythm;
  double period;
  const Eigen::VectorXd* target;
  mutable std::vector<double> warm_x, warm_f;
  template <typename T>
  bool operator()(T const* const* p, T* r) const {
    const int U = layout.units, F = static_cast<int>(rhythm->rows()), S = static_cast<int>(target->size()), step = F / S;
    std::vector<T> x(static_cast<std::size_t>(U)), f(static_cast<std::size_t>(U)), x0, f0, out;
    const bool warm = !warm_x.empty();
    for (int u = 0; u < U; ++u) {
      x[static_cast<std::size_t>(u)] = T(warm ? warm_x[static_cast<std::size_t>(u)] : 0.0);
      f[static_cast<std::size_t>(u)] = T(warm ? warm_f[static_cast<std::size_t>(u)] : 0.0);
    }
    simulate(layout, p[0], *rhythm, period, warm ? 1 : settle_periods(value_of(p[0][0]), period), x, f, x0, f0, out);
    warm_x.resize(static_cast<std::size_t>(U));
    warm_f.resize(static_cast<std::size_t>(U));
    for (int u = 0; u < U; ++u) {
      warm_x[static_cast<std::size_t>(u)] = value_of(x0[static_cast<std::size_t>(u)]);
      warm_f[static_cast<std::size_t>(u)] = value_of(f0[static_cast<std::size_t>(u)]);
    }
    for (int k = 0; k < S; ++k) {
      T fit = p[1][U];
      for (int u = 0; u < U; ++u) fit += p[1][u] * out[static_cast<std::size_t>(k * step * U + u)];
      r[k] = T((*target)[k]) - fit;
    }
    return true;
  }
};

// Outputs at the target's phases and the exact non-negative map for them.
void exact_map(const Layout& L, const std::vector<double>& p, const Eigen::MatrixXd& rhythm, double period,
               const Eigen::VectorXd& target, std::vector<double>& weights, PatternNeurons* out, Eigen::VectorXd* fitted) {
  const int U = L.units, F = static_cast<int>(rhythm.rows()), S = static_cast<int>(target.size()), step = F / S;
  std::vector<double> x(static_cast<std::size_t>(U), 0.0), f(static_cast<std::size_t>(U), 0.0), x0, f0, y;
  simulate(L, p.data(), rhythm, period, settle_periods(p[0], period), x, f, x0, f0, y);
  Eigen::MatrixXd design(S, U + 1);
  for (int k = 0; k < S; ++k) {
    for (int u = 0; u < U; ++u) design(k, u) = y[static_cast<std::size_t>(k * step * U + u)];
    design(k, U) = 1.0;
  }
  const Eigen::VectorXd w = nnls(design, target);
  weights.assign(w.data(), w.data() + w.size());
  if (fitted) *fitted = design * w;
  if (out) {
    PatternNeurons& n = *out;
    n.units = U;
    n.tau_a = p[0];
    n.mutual = p[1];
    n.s.resize(U);
    n.b.resize(U);
    n.c.resize(U, L.rhythm);
    for (int u = 0; u < U; ++u) {
      const double* q = p.data() + 2 + u * L.per_unit();
      n.s[u] = q[0];
      n.b[u] = q[1];
      for (int j = 0; j < L.rhythm; ++j) n.c(u, j) = q[2 + j];
    }
    n.weights = w.head(U);
    n.bias = w[U];
    n.x0 = Eigen::Map<const Eigen::VectorXd>(x0.data(), U);
    n.f0 = Eigen::Map<const Eigen::VectorXd>(f0.data(), U);
    n.outputs = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(y.data(), F, U);
  }
}

}  // namespace

PatternNeurons fit_pattern_neurons(const Eigen::MatrixXd& rhythm, double period, const Eigen::VectorXd& target, int units,
                                   int starts, unsigned seed, Eigen::VectorXd& fitted) {
  const Layout L{units, static_cast<int>(rhythm.cols())};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> best;
  double best_cost = std::numeric_limits<double>::infinity();
  const double scale = std::max(1e-6, rhythm.maxCoeff());  // couplings of a few units move a unit across its threshold
  // Each start runs a few iterations; the most promising then runs to convergence.
  auto solve = [&](std::vector<double>& p, std::vector<double>& w, int iterations) {
    ceres::Problem problem;
    auto* cost = new ceres::DynamicAutoDiffCostFunction<Residual, 4>(new Residual{L, &rhythm, period, &target, {}, {}});
    cost->AddParameterBlock(L.size());
    cost->AddParameterBlock(units + 1);
    cost->SetNumResiduals(static_cast<int>(target.size()));
    problem.AddResidualBlock(cost, nullptr, p.data(), w.data());
    auto bound = [&](double* block, int i, double lo, double hi) {
      problem.SetParameterLowerBound(block, i, lo);
      problem.SetParameterUpperBound(block, i, hi);
    };
    bound(p.data(), 0, 0.3, 40.0);
    // No inhibition between a muscle's units: a lone Matsuoka neuron driven by a periodic input
    // settles on one periodic response, while a mutually inhibiting pair can oscillate on its own
    // and drift from the rhythm (measured: fits that the running network did not reproduce).
    problem.SetManifold(p.data(), new ceres::SubsetManifold(L.size(), {1}));
    for (int k = 0; k < units; ++k) {
      const int o = 2 + k * L.per_unit();
      bound(p.data(), o, -20.0, 20.0);
      bound(p.data(), o + 1, 0.0, 10.0);
      for (int j = 0; j < L.rhythm; ++j) bound(p.data(), o + 2 + j, -20.0 / scale, 20.0 / scale);
    }
    for (int k = 0; k <= units; ++k) problem.SetParameterLowerBound(w.data(), k, 0.0);
    ceres::Solver::Options so;
    so.max_num_iterations = iterations;
    so.linear_solver_type = ceres::DENSE_QR;
    so.logging_type = ceres::SILENT;
    so.function_tolerance = 1e-7;
    so.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    return summary.final_cost;
  };
  const Eigen::VectorXd mean_rhythm = rhythm.colwise().mean().transpose();
  std::vector<double> best_w;
  for (int start = 0; start < starts; ++start) {
    std::vector<double> p(static_cast<std::size_t>(L.size()));
    p[0] = 1.0 + 9.0 * u(rng);
    p[1] = 0.0;
    for (int k = 0; k < units; ++k) {
      double* q = p.data() + 2 + k * L.per_unit();
      q[1] = 0.5 + 2.0 * u(rng);
      double mean_drive = 0;
      for (int j = 0; j < L.rhythm; ++j) q[2 + j] = (6.0 * u(rng) - 3.0) / scale, mean_drive += q[2 + j] * mean_rhythm[j];
      // Tonic input so that the unit crosses its threshold during the cycle: a unit that never fires
      // has no gradient to learn from.
      q[0] = mean_drive + 0.3 * (2.0 * u(rng) - 1.0);
    }
    std::vector<double> w;
    exact_map(L, p, rhythm, period, target, w, nullptr, nullptr);  // the exact map starts the weights
    const double cost = solve(p, w, 8);
    if (cost < best_cost) best_cost = cost, best = p, best_w = w;
  }
  solve(best, best_w, 60);
  PatternNeurons n;
  std::vector<double> w;
  exact_map(L, best, rhythm, period, target, w, &n, &fitted);  // converged neurons, exact map, steady start state
  return n;
}

}  // namespace cpgait
