#include "cpgait/cpg/cpg_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <cmath>
#include <cstdio>
#include <random>

#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/dynamics/rosenbrock_w.h"
#include "cpgait/cpg/pattern_layer.h"
#include "cpgait/optim/nnls.h"

namespace cpgait {
namespace {

constexpr int kFinePhases = 400;  // samples of the network's limit cycle

// The searched parameters, all dimensionless (Tr = 1): [Ta/Tr, b, a, s_0..s_{N-1}, cross couplings
// (i, j) for neurons of different pairs, row by row], then the pattern's phase in the cycle.
struct Layout {
  int pairs, neurons, n_cross, size;
  explicit Layout(int k) : pairs(k), neurons(2 * k), n_cross(2 * k * (2 * k - 2)), size(3 + 2 * k + 2 * k * (2 * k - 2) + 1) {}
  int phase() const { return size - 1; }
};

MatsuokaNetwork network_from(const Layout& L, const double* p) {
  MatsuokaNetwork n;
  const int N = L.neurons;
  n.tau_r_s = Eigen::VectorXd::Ones(N);
  n.tau_a_s = Eigen::VectorXd::Constant(N, p[0]);
  n.b = Eigen::VectorXd::Constant(N, p[1]);
  n.s = Eigen::Map<const Eigen::VectorXd>(p + 3, N);
  n.a = Eigen::MatrixXd::Zero(N, N);
  int k = 3 + N;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      if (i == j) continue;
      n.a(i, j) = (i / 2 == j / 2) ? p[2] : p[k++];
    }
  return n;
}

// One period of the network's limit cycle, sampled at kFinePhases phases from an upward crossing of
// neuron 0's mean output; false when it does not settle into oscillation.
struct LimitCycle {
  double period = 0;  // in units of Tr
  Eigen::MatrixXd outputs;            // kFinePhases x neurons
  std::vector<MatsuokaState> states;  // at each sampled phase
};

// The rhythm layer's usual size (two pairs) on fixed-size vectors: its limit cycle takes ~2,000 RK4
// steps per residual evaluation, where dynamic-size products cost more than the arithmetic. The same
// operations as matsuoka_step.
struct FixedNetwork4 {
  using V = Eigen::Vector4d;
  Eigen::Matrix4d a;
  V s, b, inv_tau_r, inv_tau_a;
  explicit FixedNetwork4(const MatsuokaNetwork& n)
      : a(n.a), s(n.s), b(n.b), inv_tau_r(n.tau_r_s.cwiseInverse()), inv_tau_a(n.tau_a_s.cwiseInverse()) {}
  [[gnu::always_inline]] void rates(const V& x, const V& f, V& dx, V& df) const {
    const V y = x.cwiseMax(0.0);
    dx = (s - x - b.cwiseProduct(f) - a * y).cwiseProduct(inv_tau_r);
    df = (y - f).cwiseProduct(inv_tau_a);
  }
  void step(V& x, V& f, double dt) const {
    V k1x, k1f, k2x, k2f, k3x, k3f, k4x, k4f;
    rates(x, f, k1x, k1f);
    rates(x + 0.5 * dt * k1x, f + 0.5 * dt * k1f, k2x, k2f);
    rates(x + 0.5 * dt * k2x, f + 0.5 * dt * k2f, k3x, k3f);
    rates(x + dt * k3x, f + dt * k3f, k4x, k4f);
    x += dt / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x);
    f += dt / 6.0 * (k1f + 2 * k2f + 2 * k3f + k4f);
  }
};

// transient_periods: estimated periods simulated from rest before sampling; tolerance: how far
// (relative to the outputs' range) the whole state may be from where it was one period earlier.
bool limit_cycle(const MatsuokaNetwork& n, LimitCycle& out, double transient_periods = 6, double tolerance = 1e-2) {
  const double w = matsuoka_natural_frequency(1.0, n.tau_a_s[0], n.b[0], std::max(n.a(0, 1), 1e-3));
  const double T_est = w > 0 ? 2 * M_PI / w : 10 * n.tau_a_s[0];
  const double dt = std::min(T_est / 200.0, 0.05);
  MatsuokaState st = MatsuokaState::resting(n);
  const int transient = static_cast<int>(std::min(transient_periods * T_est / dt, transient_periods > 10 ? 2e5 : 2e4));
  const int steps = static_cast<int>(std::min(3.5 * T_est / dt, 20000.0));
  Eigen::MatrixXd xs(n.size(), steps), fs(n.size(), steps);  // states by column: no allocation per step
  Eigen::MatrixXd y(steps, n.size());
  if (n.size() == 4) {
    const FixedNetwork4 net(n);
    Eigen::Vector4d x = st.x, f = st.f;
    for (int i = 0; i < transient; ++i) net.step(x, f, dt);
    for (int i = 0; i < steps; ++i) {
      net.step(x, f, dt);
      y.row(i) = x.cwiseMax(0.0).transpose();
      xs.col(i) = x;
      fs.col(i) = f;
    }
  } else {
    MatsuokaScratch scratch;
    const Eigen::VectorXd none;
    for (int i = 0; i < transient; ++i) matsuoka_step(n, st, dt, none, scratch);
    for (int i = 0; i < steps; ++i) {
      matsuoka_step(n, st, dt, none, scratch);
      y.row(i) = st.x.cwiseMax(0.0).transpose();
      xs.col(i) = st.x;
      fs.col(i) = st.f;
    }
  }
  const Eigen::VectorXd y0 = y.col(0);
  if (y0.maxCoeff() - y0.minCoeff() < 1e-3) return false;
  const double mean = y0.mean();
  std::vector<double> up;
  for (int i = 1; i < steps; ++i)
    if (y0[i - 1] < mean && y0[i] >= mean) up.push_back(i - 1 + (mean - y0[i - 1]) / (y0[i] - y0[i - 1]));
  if (up.size() < 3) return false;
  const double start = up[up.size() - 3], period_steps = up[up.size() - 2] - start;
  const double p2 = up[up.size() - 1] - up[up.size() - 2];
  if (std::abs(p2 - period_steps) > 0.02 * period_steps) return false;  // not settled (or not periodic)
  // The whole state must come back after a period, not only neuron 0's crossing: pairs whose relative
  // phase still drifts (slow transients, quasi-periodic motion) run away from their fit in the CPG.
  auto state_at = [&](double pos) {
    const int i = std::min(static_cast<int>(pos), steps - 2);
    const double a = pos - i;
    Eigen::VectorXd z(2 * n.size());
    z << (1 - a) * xs.col(i) + a * xs.col(i + 1), (1 - a) * fs.col(i) + a * fs.col(i + 1);
    return z;
  };
  if ((state_at(start + period_steps) - state_at(start)).cwiseAbs().maxCoeff() > tolerance * (y.maxCoeff() - y.minCoeff())) return false;
  out.period = period_steps * dt;
  out.outputs.resize(kFinePhases, n.size());
  out.states.resize(kFinePhases);
  for (int k = 0; k < kFinePhases; ++k) {
    const double pos = start + period_steps * k / kFinePhases;
    const int i = std::min(static_cast<int>(pos), steps - 2);
    const double a = pos - i;
    out.outputs.row(k) = (1 - a) * y.row(i) + a * y.row(i + 1);
    // Interpolated, not nearest: pattern neurons amplify the rhythm, so its start must be exact.
    out.states[k].x = (1 - a) * xs.col(i) + a * xs.col(i + 1);
    out.states[k].f = (1 - a) * fs.col(i) + a * fs.col(i + 1);
  }
  return true;
}

// The network's state at a phase of its limit cycle (interpolated between the sampled phases).
MatsuokaState state_at_phase(const LimitCycle& c, double phase) {
  double ph = std::fmod(phase, 1.0);
  if (ph < 0) ph += 1.0;
  const double pos = ph * kFinePhases;
  const int i = static_cast<int>(pos) % kFinePhases, j = (i + 1) % kFinePhases;
  const double a = pos - std::floor(pos);
  return {(1 - a) * c.states[static_cast<std::size_t>(i)].x + a * c.states[static_cast<std::size_t>(j)].x,
          (1 - a) * c.states[static_cast<std::size_t>(i)].f + a * c.states[static_cast<std::size_t>(j)].f};
}

// The network's outputs at the target's phases, shifted by `phase` (fraction of a cycle).
Eigen::MatrixXd at_phases(const LimitCycle& c, int samples, double phase) {
  Eigen::MatrixXd Y(samples, c.outputs.cols());
  for (int k = 0; k < samples; ++k) {
    double ph = std::fmod(static_cast<double>(k) / samples + phase, 1.0);
    if (ph < 0) ph += 1.0;
    const double pos = ph * kFinePhases;
    const int i = static_cast<int>(pos) % kFinePhases, j = (i + 1) % kFinePhases;
    const double a = pos - std::floor(pos);
    Y.row(k) = (1 - a) * c.outputs.row(i) + a * c.outputs.row(j);
  }
  return Y;
}

// Exact non-negative output map and bias for given outputs; returns the fitted patterns.
Eigen::MatrixXd best_map(const Eigen::MatrixXd& Y, const Eigen::MatrixXd& target, Eigen::MatrixXd* map, Eigen::VectorXd* bias) {
  Eigen::MatrixXd design(Y.rows(), Y.cols() + 1);
  design << Y, Eigen::VectorXd::Ones(Y.rows());
  const Eigen::MatrixXd weights = nnls_columns(design, target);  // every muscle on one design
  if (map) *map = weights.topRows(Y.cols()).transpose();
  if (bias) *bias = weights.row(Y.cols()).transpose();
  return design * weights;
}

// The rhythm layer's residual: target - the best map of the network's outputs at the pattern's phase.
// It goes through a simulation and a period detection, so its Jacobian is by forward differences with
// a relative step of 1e-4, which keeps them above the discretisation noise (Ceres' default 1e-6 does
// not); the columns are split over `threads` threads, each simulation being independent.
class RhythmResidual : public ceres::CostFunction {
 public:
  RhythmResidual(const Layout& L, const Eigen::MatrixXd& target, int threads) : L_(L), target_(target), threads_(std::max(1, threads)) {
    set_num_residuals(static_cast<int>(target.size()));
    mutable_parameter_block_sizes()->push_back(L.size);
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    residual(p[0], residuals);
    if (!jacobians || !jacobians[0]) return true;
    const int n = L_.size, m = num_residuals();
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(jacobians[0], m, n);
    const Eigen::Map<const Eigen::VectorXd> r0(residuals, m);
    auto columns = [&](int first) {
      std::vector<double> q(p[0], p[0] + n);
      Eigen::VectorXd r(m);
      for (int i = first; i < n; i += threads_) {
        const double h = q[i] != 0 ? 1e-4 * std::abs(q[i]) : 1e-4;
        q[i] += h;
        residual(q.data(), r.data());
        q[i] = p[0][i];
        J.col(i) = (r - r0) / h;
      }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads_; ++t) pool.emplace_back(columns, t);
    columns(0);
    for (auto& t : pool) t.join();
    return true;
  }

 private:
  void residual(const double* p, double* residuals) const {
    Eigen::Map<Eigen::MatrixXd> r(residuals, target_.rows(), target_.cols());
    LimitCycle c;
    if (!limit_cycle(network_from(L_, p), c)) {
      r = target_;  // no oscillation: nothing explained
      return;
    }
    r = target_ - best_map(at_phases(c, static_cast<int>(target_.rows()), p[L_.phase()]), target_, nullptr, nullptr);
  }
  Layout L_;
  const Eigen::MatrixXd& target_;
  int threads_;
};

void set_bounds(ceres::Problem& problem, double* p, const Layout& L) {
  auto bound = [&](int i, double lo, double hi) {
    problem.SetParameterLowerBound(p, i, lo);
    problem.SetParameterUpperBound(p, i, hi);
  };
  bound(0, 1.5, 20.0);  // Ta / Tr: longer adaptation only slows the network down (Tr scales it to the cycle)
  bound(1, 0.3, 10.0);  // b
  bound(2, 0.3, 6.0);   // a within a pair
  for (int i = 0; i < L.neurons; ++i) bound(3 + i, 0.2, 10.0);
  for (int i = 0; i < L.n_cross; ++i) bound(3 + L.neurons + i, 0.0, 4.0);
  bound(L.phase(), -1.0, 2.0);  // periodic: starts spread it over the cycle
}

// Gives every active muscle its own pattern neurons driven by the fitted rhythm (fitted one muscle at
// a time, in parallel) and rebuilds the model's network, map and start state around them.
void add_pattern_layer(const LimitCycle& c, double phase, const Eigen::MatrixXd& target, const CpgFitOptions& o, double scale,
                       CpgModel& m, Eigen::MatrixXd& fitted) {
  if (o.pattern_units < 1 || o.pattern_units > 2) throw std::invalid_argument("fit_cpg: pattern_units must be 0, 1 or 2");
  const int S = static_cast<int>(target.rows()), M = static_cast<int>(target.cols()), R = m.network.size(), U = o.pattern_units;
  const Eigen::MatrixXd rhythm = at_phases(c, 4 * S, phase);  // aligned: row 0 is the target's phase 0
  std::vector<int> active;
  for (int k = 0; k < M; ++k)
    if (target.col(k).maxCoeff() > o.active_threshold) active.push_back(k);
  std::vector<PatternNeurons> units(active.size());
  std::vector<Eigen::VectorXd> fits(active.size());
  {
    std::atomic<std::size_t> next{0};
    std::vector<std::thread> pool;
    const unsigned threads = std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(), static_cast<unsigned>(active.size())));
    for (unsigned t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        for (std::size_t i; (i = next++) < active.size();) {
          const Eigen::VectorXd y = target.col(active[i]);
          const unsigned seed = o.seed * 7919u + static_cast<unsigned>(active[i]);
          units[i] = fit_pattern_neurons(rhythm, c.period, y, U, o.pattern_starts, seed, fits[i]);
          // A poor fit is usually a start whose neurons never fired: try again from more starts.
          if (r_squared(y, fits[i]) < 0.85) {
            Eigen::VectorXd again;
            PatternNeurons second = fit_pattern_neurons(rhythm, c.period, y, U, 3 * o.pattern_starts, seed + 104729u, again);
            if (r_squared(y, again) > r_squared(y, fits[i])) units[i] = second, fits[i] = again;
          }
        }
      });
    for (auto& t : pool) t.join();
  }
  const int N = R + U * static_cast<int>(active.size());
  MatsuokaNetwork n;
  n.tau_r_s = Eigen::VectorXd::Constant(N, scale);  // Tr = 1 in the fit's units
  n.tau_a_s.resize(N);
  n.b.resize(N);
  n.s.resize(N);
  n.a = Eigen::MatrixXd::Zero(N, N);
  n.tau_a_s.head(R) = m.network.tau_a_s;
  n.b.head(R) = m.network.b;
  n.s.head(R) = m.network.s;
  n.a.topLeftCorner(R, R) = m.network.a;
  MatsuokaState start;
  start.x.resize(N);
  start.f.resize(N);
  start.x.head(R) = m.start.x;
  start.f.head(R) = m.start.f;
  m.output_map = Eigen::MatrixXd::Zero(M, N);
  for (int k = 0; k < M; ++k) {
    // Inactive muscles: their mean (the best constant), no neurons.
    m.output_bias[k] = std::max(0.0, target.col(k).mean());
    fitted.col(k).setConstant(m.output_bias[k]);
  }
  for (std::size_t i = 0; i < active.size(); ++i) {
    const PatternNeurons& p = units[i];
    const int first = R + U * static_cast<int>(i);
    for (int u = 0; u < U; ++u) {
      n.tau_a_s[first + u] = p.tau_a * scale;
      n.b[first + u] = p.b[u];
      n.s[first + u] = p.s[u];
      n.a.row(first + u).head(R) = p.c.row(u);
      start.x[first + u] = p.x0[u];
      start.f[first + u] = p.f0[u];
      m.output_map(active[i], first + u) = p.weights[u];
    }
    m.output_bias[active[i]] = p.bias;
    fitted.col(active[i]) = fits[i];
  }
  m.network = n;
  m.start = start;
}

}  // namespace

double r_squared(const Eigen::VectorXd& y, const Eigen::VectorXd& fit) {
  const double ss_tot = (y.array() - y.mean()).square().sum();
  const double ss_res = (y - fit).squaredNorm();
  return ss_tot > 0 ? 1.0 - ss_res / ss_tot : (ss_res == 0 ? 1.0 : 0.0);
}

std::vector<double> contact_onsets(const Eigen::VectorXd& time, const Eigen::VectorXd& force, double threshold) {
  std::vector<double> out;
  for (Eigen::Index i = 1; i < force.size(); ++i)
    if (force[i - 1] < threshold && force[i] >= threshold)
      out.push_back(time[i - 1] + (threshold - force[i - 1]) / (force[i] - force[i - 1]) * (time[i] - time[i - 1]));
  return out;
}

namespace {
// The cycles (start, end) lying inside the data.
std::vector<std::pair<double, double>> cycles_inside(const std::vector<double>& time, const std::vector<double>& starts) {
  std::vector<std::pair<double, double>> cycles;
  for (std::size_t k = 0; k + 1 < starts.size(); ++k)
    if (!time.empty() && starts[k] >= time.front() - 1e-9 && starts[k + 1] <= time.back() + 1e-9) cycles.push_back({starts[k], starts[k + 1]});
  return cycles;
}
}  // namespace

double mean_cycle_duration(const std::vector<double>& time, const std::vector<double>& starts, int* count) {
  const auto cycles = cycles_inside(time, starts);
  double sum = 0;
  for (const auto& [t0, t1] : cycles) sum += t1 - t0;
  if (count) *count = static_cast<int>(cycles.size());
  return cycles.empty() ? 0.0 : sum / static_cast<double>(cycles.size());
}

std::vector<Eigen::MatrixXd> cycle_curves(const std::vector<double>& time, const Eigen::MatrixXd& patterns,
                                          const std::vector<double>& starts, int samples, bool include_end) {
  std::vector<Eigen::MatrixXd> curves;
  for (const auto& [t0, t1] : cycles_inside(time, starts)) {
    Eigen::MatrixXd c(samples, patterns.cols());
    for (int k = 0; k < samples; ++k) {
      const double t = t0 + (t1 - t0) * k / (include_end ? samples - 1 : samples);
      const std::size_t i = std::min<std::size_t>(std::upper_bound(time.begin(), time.end(), t) - time.begin(), time.size() - 1);
      const std::size_t i0 = i == 0 ? 0 : i - 1;
      const double a = time[i] > time[i0] ? std::clamp((t - time[i0]) / (time[i] - time[i0]), 0.0, 1.0) : 0.0;
      c.row(k) = (1 - a) * patterns.row(static_cast<Eigen::Index>(i0)) + a * patterns.row(static_cast<Eigen::Index>(i));
    }
    curves.push_back(std::move(c));
  }
  return curves;
}

Eigen::MatrixXd cycle_average(const std::vector<double>& time, const Eigen::MatrixXd& patterns,
                              const std::vector<double>& starts, int samples) {
  const auto curves = cycle_curves(time, patterns, starts, samples);
  if (curves.empty())
    throw InputError("gait cycles", 0, "cycle_starts", "no full gait cycle (two heel strikes) lies inside the patterns' time range");
  Eigen::MatrixXd avg = Eigen::MatrixXd::Zero(samples, patterns.cols());
  for (const auto& c : curves) avg += c;
  return avg / static_cast<double>(curves.size());
}

CpgFitResult fit_cpg(const Eigen::MatrixXd& target, double cycle_s, const std::vector<std::string>& names, const CpgFitOptions& o) {
  const auto start_time = std::chrono::steady_clock::now();
  const Layout L(o.pairs);
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> best;
  CpgFitResult result;
  // Starting points first (deterministic for a seed), then the starts run on all cores.
  std::vector<std::vector<double>> starts(o.starts, std::vector<double>(L.size));
  for (int start = 0; start < o.starts; ++start) {
    auto& p = starts[start];
    // Start 0: Matsuoka's classic pairs (Ta/Tr 10, b 2.5, a 1.5, s 5) in a ring, each pair's neurons
    // weakly inhibiting the next pair's (the last pair's the first's, crossed): it settles within a
    // period or two with the pairs' phases evenly spread (quadrature for two pairs), where uniform
    // weak couplings between all pairs take some 25 periods to get there. The others random.
    const bool classic = start == 0;
    p[0] = classic ? 10.0 : 3.0 + 17.0 * u(rng);
    p[1] = classic ? 2.5 : 1.0 + 4.0 * u(rng);
    p[2] = classic ? 1.5 : 0.8 + 2.0 * u(rng);
    for (int i = 0; i < L.neurons; ++i) p[3 + i] = classic ? 5.0 : 1.0 + 6.0 * u(rng);
    int k = 3 + L.neurons;
    for (int i = 0; i < L.neurons; ++i)
      for (int j = 0; j < L.neurons; ++j) {
        if (i / 2 == j / 2) continue;
        const int pair = i / 2, from = j / 2;
        const bool ring = pair > 0 ? from == pair - 1 && j % 2 == i % 2 : from == L.pairs - 1 && j % 2 != i % 2;
        p[k++] = classic ? (ring ? 0.3 : 0.0) : 1.5 * u(rng);
      }
    p[L.phase()] = static_cast<double>(start % 4) / 4.0;
  }
  const std::vector<double> ring_start = starts[0];  // the fallback should optimisation leave no periodic network
  std::vector<double> costs(o.starts, std::numeric_limits<double>::infinity());
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int jacobian_threads = std::max(1, cores / o.starts);  // cores the starts leave idle
  auto solve = [&](int start) {
    auto& p = starts[start];
    ceres::Problem problem;
    problem.AddResidualBlock(new RhythmResidual(L, target, jacobian_threads), nullptr, p.data());
    set_bounds(problem, p.data(), L);
    ceres::Solver::Options so;
    so.max_num_iterations = o.max_iterations;
    so.linear_solver_type = ceres::DENSE_QR;
    so.logging_type = ceres::SILENT;
    so.function_tolerance = 1e-10;
    so.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    costs[start] = summary.final_cost;
  };
  {
    const int threads = std::min(cores, o.starts);
    std::atomic<int> next{0};
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t)
      pool.emplace_back([&] {
        for (int k; (k = next++) < o.starts;) solve(k);
      });
    for (auto& t : pool) t.join();
  }
  result.summary.rhythm_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  // The model: network in seconds (period = cycle), exact map, state at the cycle's start. The fit saw
  // each network after a few periods; the CPG runs on its attractor, which slow modes (the pairs'
  // relative phase) reach later: so the best start whose network settles on a periodic attractor
  // within a long run, sampled there.
  std::vector<int> order(static_cast<std::size_t>(o.starts));
  for (int k = 0; k < o.starts; ++k) order[static_cast<std::size_t>(k)] = k;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return costs[a] < costs[b]; });
  LimitCycle c;
  for (int start : order)
    if (std::isfinite(costs[start]) && limit_cycle(network_from(L, starts[start].data()), c, 300.0, 1e-3)) {
      best = starts[start], result.summary.best_start = start;
      break;
    }
  if (best.empty() && limit_cycle(network_from(L, ring_start.data()), c, 300.0, 1e-3)) best = ring_start, result.summary.best_start = 0;
  if (best.empty()) throw std::runtime_error("fit_cpg: no network settled on a periodic oscillation");
  const MatsuokaNetwork unit = network_from(L, best.data());
  CpgModel& m = result.model;
  const double scale = cycle_s / c.period;
  m.network = unit;
  m.network.tau_r_s *= scale;
  m.network.tau_a_s *= scale;
  m.cycle_s = cycle_s;
  m.muscle_names = names;
  double ph = std::fmod(best[L.phase()], 1.0);
  if (ph < 0) ph += 1.0;
  const Eigen::MatrixXd Y = at_phases(c, static_cast<int>(target.rows()), ph);
  result.fitted = best_map(Y, target, &m.output_map, &m.output_bias);
  result.target = target;
  m.start = state_at_phase(c, ph);
  if (o.pattern_units > 0) add_pattern_layer(c, ph, target, o, scale, m, result.fitted);
  m.feedback_gains = Eigen::MatrixXd::Zero(m.network.size(), 0);
  // Quality.
  auto& s = result.summary;
  s.r_squared.resize(target.cols());
  double sum = 0;
  for (Eigen::Index k = 0; k < target.cols(); ++k) {
    s.r_squared[k] = r_squared(target.col(k), result.fitted.col(k));
    if (target.col(k).maxCoeff() > o.active_threshold) sum += s.r_squared[k], ++s.active_muscles;
  }
  s.mean_r_squared_active = s.active_muscles ? sum / s.active_muscles : 0;
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return result;
}

std::string CpgFitSummary::BriefReport() const {
  char buf[200];
  std::snprintf(buf, sizeof buf, "CPG fit: mean R^2 %.4f over %d active muscles, best of start %d, %.2f s (rhythm %.2f s)",
                mean_r_squared_active, active_muscles, best_start, seconds, rhythm_seconds);
  return buf;
}

Eigen::VectorXd cpg_excitations(const CpgModel& m, const Eigen::VectorXd& y) {
  return (m.amplitude * (m.output_map * y + m.output_bias)).cwiseMax(0.0).cwiseMin(1.0);
}

Eigen::VectorXd cpg_excitations(const CpgModel& m, const Eigen::VectorXd& y, const Eigen::SparseMatrix<double>& output_map) {
  return (m.amplitude * (output_map * y + m.output_bias)).cwiseMax(0.0).cwiseMin(1.0);
}

MatsuokaNetwork network_at_speed(const CpgModel& m) {
  MatsuokaNetwork n = m.network;
  n.tau_r_s /= m.speed;
  n.tau_a_s /= m.speed;
  return n;
}

CpgRun run_cpg(const CpgModel& m, double duration_s, double dt, const Eigen::MatrixXd& feedback) {
  CpgRun r;
  const int steps = static_cast<int>(std::lround(duration_s / dt));
  const MatsuokaNetwork n = network_at_speed(m);
  MatsuokaState st = m.start;
  Eigen::MatrixXd input;
  if (feedback.rows() > 0) {
    if (feedback.cols() != m.feedback_gains.cols())
      throw InputError("cpg run", 0, "feedback", "feedback has " + std::to_string(feedback.cols()) + " signals, the model's gains " +
                                                   std::to_string(m.feedback_gains.cols()));
    input = feedback * m.feedback_gains.transpose();
  }
  r.neurons = simulate_matsuoka(n, st, dt, steps, input);
  r.excitations.resize(steps, m.output_map.rows());
  for (int i = 0; i < steps; ++i) {
    r.time_s.push_back((i + 1) * dt);
    r.excitations.row(i) = cpg_excitations(m, r.neurons.row(i).transpose()).transpose();
  }
  return r;
}

CpgRun run_cpg_transition(const CpgModel& a, const CpgModel& b, double t0, double t1, double duration_s, double dt) {
  if (a.network.size() != b.network.size() || a.output_map.rows() != b.output_map.rows())
    throw InputError("cpg transition", 0, "models", "the two models differ in neurons or muscles");
  CpgRun r;
  const int steps = static_cast<int>(std::lround(duration_s / dt));
  MatsuokaState st = a.start;
  r.neurons.resize(steps, a.network.size());
  r.excitations.resize(steps, a.output_map.rows());
  for (int i = 0; i < steps; ++i) {
    const double t = i * dt;
    const double w = t <= t0 ? 0.0 : t >= t1 ? 1.0 : 0.5 - 0.5 * std::cos(M_PI * (t - t0) / (t1 - t0));
    CpgModel m = a;
    const MatsuokaNetwork na = network_at_speed(a), nb = network_at_speed(b);
    m.speed = 1.0;
    m.network.tau_r_s = (1 - w) * na.tau_r_s + w * nb.tau_r_s;
    m.network.tau_a_s = (1 - w) * na.tau_a_s + w * nb.tau_a_s;
    m.network.b = (1 - w) * na.b + w * nb.b;
    m.network.s = (1 - w) * na.s + w * nb.s;
    m.network.a = (1 - w) * na.a + w * nb.a;
    m.output_map = (1 - w) * a.output_map + w * b.output_map;
    m.output_bias = (1 - w) * a.output_bias + w * b.output_bias;
    m.amplitude = (1 - w) * a.amplitude + w * b.amplitude;
    r.neurons.row(i) = simulate_matsuoka(m.network, st, dt, 1).row(0);
    r.excitations.row(i) = cpg_excitations(m, r.neurons.row(i).transpose()).transpose();
    r.time_s.push_back((i + 1) * dt);
  }
  return r;
}

nlohmann::json CpgModel::to_json() const {
  auto vec = [](const Eigen::VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
  auto mat = [&](const Eigen::MatrixXd& M) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index i = 0; i < M.rows(); ++i) rows.push_back(vec(M.row(i).transpose()));
    return rows;
  };
  nlohmann::json j = {{"schema", "cpgait.cpg/1"},
          {"network", {{"tau_r_s", vec(network.tau_r_s)}, {"tau_a_s", vec(network.tau_a_s)}, {"b", vec(network.b)},
                       {"s", vec(network.s)}, {"a", mat(network.a)}}},
          {"start", {{"x", vec(start.x)}, {"f", vec(start.f)}}},
          {"cycle_s", cycle_s},
          {"speed", speed},
          {"amplitude", amplitude},
          {"muscles", muscle_names},
          {"output_map", mat(output_map)},
          {"output_bias", vec(output_bias)},
          {"feedback", {{"signals", feedback_signals}, {"gains", mat(feedback_gains)}}}};
  if (controller)
    j["controller"] = controller->to_json();
  for (const ScheduledController& e : speed_schedule) {
    nlohmann::json k = e.controller.to_json();
    k["amplitude"] = e.amplitude;
    j["controller_schedule"].push_back(k);
  }
  return j;
}

CpgModel scheduled_at_speed(const CpgModel& cpg, double knob) {
  if (!cpg.controller || cpg.speed_schedule.empty()) return cpg;
  std::vector<ScheduledController> tuned = cpg.speed_schedule;
  tuned.push_back({*cpg.controller, cpg.amplitude});
  std::sort(tuned.begin(), tuned.end(), [](const auto& a, const auto& b) { return a.controller.speed < b.controller.speed; });
  std::size_t hi = 0;
  while (hi + 1 < tuned.size() && tuned[hi].controller.speed < knob) ++hi;
  const std::size_t lo = hi > 0 && tuned[hi].controller.speed > knob ? hi - 1 : hi;
  const ScheduledController &a = tuned[lo], &b = tuned[hi];
  const double span = b.controller.speed - a.controller.speed;
  const double w = span > 0 ? std::clamp((knob - a.controller.speed) / span, 0.0, 1.0) : 0.0;
  // At a tuned knob (w 0 or 1), its own values exactly.
  auto lin = [w](double x, double y) { return w == 0 ? x : w == 1 ? y : (1 - w) * x + w * y; };
  auto geo = [&](double x, double y) { return w == 0 || w == 1 || !(x > 0 && y > 0) ? lin(x, y) : std::exp((1 - w) * std::log(x) + w * std::log(y)); };
  CpgModel m = cpg;
  CpgController& k = *m.controller;
  k.reflex_kp = geo(a.controller.reflex_kp, b.controller.reflex_kp);
  k.reflex_kv = geo(a.controller.reflex_kv, b.controller.reflex_kv);
  k.trunk_kp = lin(a.controller.trunk_kp, b.controller.trunk_kp);
  k.trunk_kv = lin(a.controller.trunk_kv, b.controller.trunk_kv);
  k.lateral_d = lin(a.controller.lateral_d, b.controller.lateral_d);
  k.lateral_v = lin(a.controller.lateral_v, b.controller.lateral_v);
  k.sagittal_d = lin(a.controller.sagittal_d, b.controller.sagittal_d);
  k.sagittal_v = lin(a.controller.sagittal_v, b.controller.sagittal_v);
  k.stance_lateral_d = lin(a.controller.stance_lateral_d, b.controller.stance_lateral_d);
  k.stance_lateral_v = lin(a.controller.stance_lateral_v, b.controller.stance_lateral_v);
  k.swing_world = lin(a.controller.swing_world, b.controller.swing_world);
  k.ankle_d = lin(a.controller.ankle_d, b.controller.ankle_d);
  k.ankle_v = lin(a.controller.ankle_v, b.controller.ankle_v);
  k.entrainment = lin(a.controller.entrainment, b.controller.entrainment);
  k.entrainment_phase_r = lin(a.controller.entrainment_phase_r, b.controller.entrainment_phase_r);
  k.entrainment_phase_l = lin(a.controller.entrainment_phase_l, b.controller.entrainment_phase_l);
  k.speed = knob;
  m.amplitude = geo(a.amplitude, b.amplitude);
  return m;
}

nlohmann::json CpgController::to_json() const {
  return {{"reflex_kp", reflex_kp},
          {"reflex_kv", reflex_kv},
          {"phase_reference", phase_reference},
          {"pelvis_residuals", pelvis_residuals},
          {"start_time_s", start_time_s},
          {"begin_time_s", begin_time_s},
          {"speed", speed},
          {"foot_spheres", foot_spheres},
          {"trunk_kp", trunk_kp},
          {"trunk_kv", trunk_kv},
          {"swing_world", swing_world},
          {"entrainment", {{"share", entrainment}, {"phase_r", entrainment_phase_r}, {"phase_l", entrainment_phase_l}}},
          {"foot_placement", {{"lateral_d", lateral_d}, {"lateral_v_s", lateral_v}, {"sagittal_d", sagittal_d}, {"sagittal_v_s", sagittal_v}}},
          {"stance_hold", {{"lateral_d", stance_lateral_d}, {"lateral_v_s", stance_lateral_v}}},
          {"ankle_strategy", {{"lateral_d_rad_per_m", ankle_d}, {"lateral_v_rad_s_per_m", ankle_v}}},
          {"simulation", {{"control_interval_s", control_interval_s}, {"integrator", integrator}, {"tolerance", integrator_tolerance}}}};
}

CpgModel CpgModel::from_json(const nlohmann::json& j, const std::string& source) {
  auto fail = [&](const std::string& field, const std::string& msg) { throw InputError(source, 0, field, msg); };
  auto vec = [&](const nlohmann::json& v, const std::string& field, Eigen::Index n) {
    if (!v.is_array() || (n >= 0 && static_cast<Eigen::Index>(v.size()) != n)) fail(field, "expected an array of " + std::to_string(n) + " numbers");
    Eigen::VectorXd out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number()) fail(field, "expected numbers");
      out[static_cast<Eigen::Index>(i)] = v[i].get<double>();
    }
    return out;
  };
  auto mat = [&](const nlohmann::json& v, const std::string& field, Eigen::Index rows, Eigen::Index cols) {
    if (!v.is_array() || static_cast<Eigen::Index>(v.size()) != rows) fail(field, "expected " + std::to_string(rows) + " rows");
    Eigen::MatrixXd out(rows, cols);
    for (Eigen::Index i = 0; i < rows; ++i) out.row(i) = vec(v[i], field, cols).transpose();
    return out;
  };
  // A member or its fallback when absent; mistyped, an InputError naming it (at.key).
  auto field_or = [&](const nlohmann::json& o, const char* key, auto fallback, const std::string& at) { return json_field_or(o, key, fallback, source, at); };
  try {
    CpgModel m;
    if (!j.is_object()) fail("", "expected a CPG JSON object (cpgait cpg fit's output)");
    const auto& n = j.at("network");
    m.network.s = vec(n.at("s"), "network.s", -1);
    const Eigen::Index N = m.network.s.size();
    m.network.tau_r_s = vec(n.at("tau_r_s"), "network.tau_r_s", N);
    m.network.tau_a_s = vec(n.at("tau_a_s"), "network.tau_a_s", N);
    m.network.b = vec(n.at("b"), "network.b", N);
    m.network.a = mat(n.at("a"), "network.a", N, N);
    if ((m.network.tau_r_s.array() <= 0).any() || (m.network.tau_a_s.array() <= 0).any()) fail("network.tau", "time constants must be positive");
    m.start.x = vec(j.at("start").at("x"), "start.x", N);
    m.start.f = vec(j.at("start").at("f"), "start.f", N);
    m.cycle_s = field_or(j, "cycle_s", 1.0, "");
    m.speed = field_or(j, "speed", 1.0, "");
    m.amplitude = field_or(j, "amplitude", 1.0, "");
    if (!(m.speed > 0)) fail("speed", "must be positive");
    m.muscle_names = json_field<std::vector<std::string>>(j, "muscles", source, "");
    const Eigen::Index M = static_cast<Eigen::Index>(m.muscle_names.size());
    m.output_map = mat(j.at("output_map"), "output_map", M, N);
    m.output_bias = vec(j.at("output_bias"), "output_bias", M);
    if ((m.output_map.array() < 0).any() || (m.output_bias.array() < 0).any()) fail("output_map", "weights must be non-negative");
    if (j.contains("feedback")) {
      if (!j["feedback"].is_object()) fail("feedback", "expected {\"signals\", \"gains\"}");
      m.feedback_signals = field_or(j["feedback"], "signals", std::vector<std::string>{}, "feedback");
      m.feedback_gains = m.feedback_signals.empty() ? Eigen::MatrixXd::Zero(N, 0)
                                                    : mat(j["feedback"].at("gains"), "feedback.gains", N, static_cast<Eigen::Index>(m.feedback_signals.size()));
    } else {
      m.feedback_gains = Eigen::MatrixXd::Zero(N, 0);
    }
    // A controller's JSON (CpgController::to_json); field: where it sits, for errors.
    auto controller = [&](const nlohmann::json& c, const std::string& field) {
      if (!c.is_object()) fail(field, "expected a controller object (reflex, balance and simulation settings)");
      CpgController k;
      k.reflex_kp = field_or(c, "reflex_kp", k.reflex_kp, field);
      k.reflex_kv = field_or(c, "reflex_kv", k.reflex_kv, field);
      k.phase_reference = field_or(c, "phase_reference", k.phase_reference, field);
      k.pelvis_residuals = field_or(c, "pelvis_residuals", k.pelvis_residuals, field);
      k.start_time_s = field_or(c, "start_time_s", k.start_time_s, field);
      k.begin_time_s = field_or(c, "begin_time_s", k.begin_time_s, field);
      k.speed = field_or(c, "speed", k.speed, field);
      k.foot_spheres = field_or(c, "foot_spheres", k.foot_spheres, field);
      if (k.foot_spheres != 0 && k.foot_spheres != 2 && k.foot_spheres != 5)
        fail(field + ".foot_spheres", "the feet it was tuned on: 2 or 5 spheres per foot, or 0 for a contact file");
      k.trunk_kp = field_or(c, "trunk_kp", k.trunk_kp, field);
      k.trunk_kv = field_or(c, "trunk_kv", k.trunk_kv, field);
      k.swing_world = field_or(c, "swing_world", k.swing_world, field);
      if (c.contains("entrainment")) {
        const auto& e = c["entrainment"];
        if (!e.is_object()) fail(field + ".entrainment", "expected {\"share\", \"phase_r\", \"phase_l\"}");
        k.entrainment = field_or(e, "share", k.entrainment, field + ".entrainment");
        k.entrainment_phase_r = field_or(e, "phase_r", k.entrainment_phase_r, field + ".entrainment");
        k.entrainment_phase_l = field_or(e, "phase_l", k.entrainment_phase_l, field + ".entrainment");
        if (!(k.entrainment >= 0 && k.entrainment <= 1)) fail(field + ".entrainment.share", "the share of the phase error made up at a touchdown lies in [0, 1]");
        if (!std::isfinite(k.entrainment_phase_r) || !std::isfinite(k.entrainment_phase_l)) fail(field + ".entrainment.phase_r", "heel-strike phases must be finite numbers");
      }
      if (c.contains("foot_placement")) {
        const auto& fp = c["foot_placement"];
        if (!fp.is_object()) fail(field + ".foot_placement", "expected {\"lateral_d\", \"lateral_v_s\", \"sagittal_d\", \"sagittal_v_s\"}");
        k.lateral_d = field_or(fp, "lateral_d", k.lateral_d, field + ".foot_placement");
        k.lateral_v = field_or(fp, "lateral_v_s", k.lateral_v, field + ".foot_placement");
        k.sagittal_d = field_or(fp, "sagittal_d", k.sagittal_d, field + ".foot_placement");
        k.sagittal_v = field_or(fp, "sagittal_v_s", k.sagittal_v, field + ".foot_placement");
      }
      if (c.contains("stance_hold")) {
        const auto& sh = c["stance_hold"];
        if (!sh.is_object()) fail(field + ".stance_hold", "expected {\"lateral_d\", \"lateral_v_s\"}");
        k.stance_lateral_d = field_or(sh, "lateral_d", k.stance_lateral_d, field + ".stance_hold");
        k.stance_lateral_v = field_or(sh, "lateral_v_s", k.stance_lateral_v, field + ".stance_hold");
      }
      if (c.contains("ankle_strategy")) {
        const auto& as = c["ankle_strategy"];
        if (!as.is_object()) fail(field + ".ankle_strategy", "expected {\"lateral_d_rad_per_m\", \"lateral_v_rad_s_per_m\"}");
        k.ankle_d = field_or(as, "lateral_d_rad_per_m", k.ankle_d, field + ".ankle_strategy");
        k.ankle_v = field_or(as, "lateral_v_rad_s_per_m", k.ankle_v, field + ".ankle_strategy");
      }
      if (c.contains("simulation")) {
        const auto& sim = c["simulation"];
        if (!sim.is_object()) fail(field + ".simulation", "expected {\"control_interval_s\", \"integrator\", \"tolerance\"}");
        k.control_interval_s = field_or(sim, "control_interval_s", k.control_interval_s, field + ".simulation");
        k.integrator_tolerance = field_or(sim, "tolerance", k.integrator_tolerance, field + ".simulation");
        k.integrator = field_or(sim, "integrator", k.integrator, field + ".simulation");
        if (!(k.control_interval_s >= 0 && k.control_interval_s <= 0.01))
          fail(field + ".simulation.control_interval_s", "the controller's interval lies in (0, 0.01] s (0: not recorded)");
        if (!(k.integrator_tolerance >= 0 && k.integrator_tolerance <= 0.1))
          fail(field + ".simulation.tolerance", "the integrator's tolerance lies in (0, 0.1] (0: not recorded)");
        if (!k.integrator.empty() && !w_method_named(k.integrator))
          fail(field + ".simulation.integrator", "\"ros34pw2\", \"rosenbrock\" or \"linearly_implicit_euler\" (empty: not recorded), not \"" + k.integrator + "\"");
      }
      for (double v : {k.trunk_kp, k.trunk_kv, k.lateral_d, k.lateral_v, k.sagittal_d, k.sagittal_v, k.stance_lateral_d, k.stance_lateral_v, k.swing_world, k.ankle_d, k.ankle_v})
        if (!std::isfinite(v)) fail(field, "balance gains must be finite numbers");
      if (!(k.reflex_kp >= 0) || !(k.reflex_kv >= 0)) fail(field + ".reflex_kp", "reflex gains must be non-negative");
      if (!(k.speed > 0)) fail(field + ".speed", "the speed knob it was tuned at must be positive");
      return k;
    };
    if (j.contains("controller")) m.controller = controller(j["controller"], "controller");
    if (j.contains("controller_schedule")) {
      if (!m.controller) fail("controller_schedule", "a schedule needs the controller it extends");
      if (!j["controller_schedule"].is_array()) fail("controller_schedule", "expected an array of controllers, one per speed knob");
      for (std::size_t i = 0; i < j["controller_schedule"].size(); ++i) {
        const std::string field = "controller_schedule[" + std::to_string(i) + "]";
        const auto& e = j["controller_schedule"][i];
        ScheduledController s{controller(e, field), field_or(e, "amplitude", m.amplitude, field)};
        if (!(s.amplitude >= 0)) fail(field + ".amplitude", "must be non-negative");
        m.speed_schedule.push_back(s);
      }
    }
    return m;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(source, 0, "", std::string("unexpected CPG JSON shape: ") + e.what());
  }
}

}  // namespace cpgait
