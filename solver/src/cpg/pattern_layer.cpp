#include "cpgait/cpg/pattern_layer.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "cpgait/optim/nnls.h"

namespace cpgait {
namespace {

// Parameters: block 0 = [tau_a, then per unit: s, b, c_1..c_R]; block 1 = [weights..., bias].
struct Layout {
  int units, rhythm;
  int per_unit() const { return 2 + rhythm; }
  int size() const { return 1 + units * per_unit(); }
  const double* unit(const double* p, int u) const { return p + 1 + u * per_unit(); }
};

template <typename T>
T relu(const T& v) {
  return v > T(0) ? v : T(0);
}

// One unit driven by the periodic rhythm (RK4, the drive interpolated within a step) from (x, f), for
// `settle` periods and then one recorded period: (x0, f0) is the recorded period's start state and
// out[k] its output at fine phase k. q = [s, b, c_1..c_R]. The units do not interact, so each is
// simulated alone: forward-mode derivatives then carry only its own parameters.
template <typename T>
void simulate_unit(const T& tau_a, const T* q, const Eigen::MatrixXd& rhythm, double period, int settle, T& x, T& f, T& x0,
                   T& f0, std::vector<T>& out) {
  const int F = static_cast<int>(rhythm.rows()), R = static_cast<int>(rhythm.cols());
  const double dt = period / F;
  std::vector<T> drive(static_cast<std::size_t>(F));
  for (int k = 0; k < F; ++k) {
    T d(0.0);
    for (int j = 0; j < R; ++j) d += q[2 + j] * rhythm(k, j);
    drive[static_cast<std::size_t>(k)] = d;
  }
  const T inv_tau_a = T(1.0) / tau_a;
  auto rates = [&](const T& xs, const T& fs, const T& d, T& dx, T& df) {
    dx = q[0] - xs - q[1] * fs - d;
    df = (relu(xs) - fs) * inv_tau_a;
  };
  out.resize(static_cast<std::size_t>(F));
  T k1x, k1f, k2x, k2f, k3x, k3f, k4x, k4f;
  for (int cycle = 0; cycle <= settle; ++cycle)
    for (int k = 0; k < F; ++k) {
      const bool record = cycle == settle;
      if (record && k == 0) x0 = x, f0 = f;
      if (record) out[static_cast<std::size_t>(k)] = relu(x);
      const T& d0 = drive[static_cast<std::size_t>(k)];
      const T& d1 = drive[static_cast<std::size_t>((k + 1) % F)];
      const T dh = 0.5 * (d0 + d1);
      rates(x, f, d0, k1x, k1f);
      rates(x + (0.5 * dt) * k1x, f + (0.5 * dt) * k1f, dh, k2x, k2f);
      rates(x + (0.5 * dt) * k2x, f + (0.5 * dt) * k2f, dh, k3x, k3f);
      rates(x + dt * k3x, f + dt * k3f, d1, k4x, k4f);
      x += (dt / 6.0) * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
      f += (dt / 6.0) * (k1f + 2.0 * k2f + 2.0 * k3f + k4f);
    }
}

// Periods to simulate before the recorded one: the slowest transient (Ta) decays to 1e-3.
int settle_periods(double tau_a, double period) { return 1 + static_cast<int>(std::ceil(7.0 * std::max(tau_a, 1.0) / period)); }

// The residual target - (weights . outputs + bias) at the target's phases, with its Jacobian: each
// unit's outputs carry forward-mode derivatives in [tau_a, s, b, c_1..c_R] (a Jet of N >= 3 + R); the
// weights and bias enter linearly. The steady state of the previous evaluation starts the next
// (parameters change little between Ceres' evaluations), so one settling period suffices after the
// first call.
class Residual : public ceres::CostFunction {
 public:
  Residual(const Layout& L, const Eigen::MatrixXd& rhythm, double period, const Eigen::VectorXd& target)
      : L_(L), rhythm_(rhythm), period_(period), target_(target), warm_x_(static_cast<std::size_t>(L.units), 0.0),
        warm_f_(static_cast<std::size_t>(L.units), 0.0) {
    set_num_residuals(static_cast<int>(target.size()));
    mutable_parameter_block_sizes()->push_back(L.size());
    mutable_parameter_block_sizes()->push_back(L.units + 1);
  }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    const int U = L_.units, S = static_cast<int>(target_.size()), step = static_cast<int>(rhythm_.rows()) / S;
    const int settle = warm_ ? 1 : settle_periods(p[0][0], period_);
    const bool jac0 = jacobians && jacobians[0];
    Eigen::MatrixXd y(S, U);
    // dy[u]: S x (1 + per_unit) derivatives of unit u's outputs in [tau_a, its own parameters].
    std::vector<Eigen::MatrixXd> dy(static_cast<std::size_t>(U));
    for (int u = 0; u < U; ++u) {
      if (!jac0) {
        std::vector<double> out;
        double x0, f0;
        simulate_unit(p[0][0], L_.unit(p[0], u), rhythm_, period_, settle, warm_x_[u], warm_f_[u], x0, f0, out);
        for (int k = 0; k < S; ++k) y(k, u) = out[static_cast<std::size_t>(k * step)];
        warm_x_[u] = x0, warm_f_[u] = f0;
      } else if (L_.per_unit() + 1 <= 8) {
        with_jets<8>(p[0], u, settle, step, y, dy[static_cast<std::size_t>(u)]);
      } else {
        with_jets<16>(p[0], u, settle, step, y, dy[static_cast<std::size_t>(u)]);
      }
    }
    warm_ = true;
    const double* w = p[1];
    for (int k = 0; k < S; ++k) residuals[k] = target_[k] - w[U] - y.row(k).dot(Eigen::Map<const Eigen::VectorXd>(w, U));
    if (!jacobians) return true;
    if (jac0) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(jacobians[0], S, L_.size());
      J.col(0).setZero();
      for (int u = 0; u < U; ++u) {
        const Eigen::MatrixXd& d = dy[static_cast<std::size_t>(u)];
        J.col(0) -= w[u] * d.col(0);
        J.middleCols(1 + u * L_.per_unit(), L_.per_unit()) = -w[u] * d.rightCols(L_.per_unit());
      }
    }
    if (jacobians[1]) {
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(jacobians[1], S, U + 1);
      J.leftCols(U) = -y;
      J.col(U).setConstant(-1.0);
    }
    return true;
  }

 private:
  template <int N>
  void with_jets(const double* p, int u, int settle, int step, Eigen::MatrixXd& y, Eigen::MatrixXd& dy) const {
    using J = ceres::Jet<double, N>;
    const int P = L_.per_unit(), S = static_cast<int>(y.rows());
    if (P + 1 > N) throw std::invalid_argument("fit_pattern_neurons: too many rhythm neurons");
    const double* q = L_.unit(p, u);
    std::vector<J> qj(static_cast<std::size_t>(P));
    for (int i = 0; i < P; ++i) qj[static_cast<std::size_t>(i)] = J(q[i], 1 + i);
    J x(warm_x_[u]), f(warm_f_[u]), x0, f0;
    std::vector<J> out;
    simulate_unit(J(p[0], 0), qj.data(), rhythm_, period_, settle, x, f, x0, f0, out);
    dy.resize(S, P + 1);
    for (int k = 0; k < S; ++k) {
      const J& o = out[static_cast<std::size_t>(k * step)];
      y(k, u) = o.a;
      dy.row(k) = o.v.head(P + 1).transpose();
    }
    warm_x_[u] = x0.a, warm_f_[u] = f0.a;
  }

  Layout L_;
  const Eigen::MatrixXd& rhythm_;
  double period_;
  const Eigen::VectorXd& target_;
  mutable std::vector<double> warm_x_, warm_f_;
  mutable bool warm_ = false;
};

// Outputs at the target's phases and the exact non-negative map for them. Returns the pattern's drift:
// the largest change of the mapped output from the recorded period to the next, which is not small
// where the unit has no unique periodic response to the rhythm (it then runs away from its fit).
double exact_map(const Layout& L, const std::vector<double>& p, const Eigen::MatrixXd& rhythm, double period,
                 const Eigen::VectorXd& target, std::vector<double>& weights, PatternNeurons* out, Eigen::VectorXd* fitted) {
  const int U = L.units, F = static_cast<int>(rhythm.rows()), S = static_cast<int>(target.size()), step = F / S;
  Eigen::MatrixXd design(S, U + 1), outputs(F, U), change(F, U);
  Eigen::VectorXd x0(U), f0(U);
  for (int u = 0; u < U; ++u) {
    double x = 0, f = 0, x1, f1;
    std::vector<double> y, next;
    simulate_unit(p[0], L.unit(p.data(), u), rhythm, period, settle_periods(p[0], period), x, f, x0[u], f0[u], y);
    simulate_unit(p[0], L.unit(p.data(), u), rhythm, period, 0, x, f, x1, f1, next);
    outputs.col(u) = Eigen::Map<const Eigen::VectorXd>(y.data(), F);
    change.col(u) = Eigen::Map<const Eigen::VectorXd>(next.data(), F) - outputs.col(u);
    for (int k = 0; k < S; ++k) design(k, u) = y[static_cast<std::size_t>(k * step)];
  }
  design.col(U).setOnes();
  const Eigen::VectorXd w = nnls(design, target);
  weights.assign(w.data(), w.data() + w.size());
  if (fitted) *fitted = design * w;
  if (out) {
    PatternNeurons& n = *out;
    n.units = U;
    n.tau_a = p[0];
    n.s.resize(U);
    n.b.resize(U);
    n.c.resize(U, L.rhythm);
    for (int u = 0; u < U; ++u) {
      const double* q = L.unit(p.data(), u);
      n.s[u] = q[0];
      n.b[u] = q[1];
      for (int j = 0; j < L.rhythm; ++j) n.c(u, j) = q[2 + j];
    }
    n.weights = w.head(U);
    n.bias = w[U];
    n.x0 = x0;
    n.f0 = f0;
    n.outputs = outputs;
  }
  return (change * w.head(U)).cwiseAbs().maxCoeff();
}

// Mapped outputs that change by more than this from one period to the next are not a periodic fit.
constexpr double kMaxDrift = 1e-3;

}  // namespace

PatternNeurons fit_pattern_neurons(const Eigen::MatrixXd& fine_rhythm, double period, const Eigen::VectorXd& target, int units,
                                   int starts, unsigned seed, Eigen::VectorXd& fitted) {
  const Layout L{units, static_cast<int>(fine_rhythm.cols())};
  const int S = static_cast<int>(target.size()), fine = static_cast<int>(fine_rhythm.rows()) / S;
  if (fine < 1 || fine * S != fine_rhythm.rows()) throw std::invalid_argument("fit_pattern_neurons: rhythm rows must be a multiple of the target's");
  // The search runs one step per second target phase (when they are even in number): twice as fast,
  // and the final simulation at the fine phases makes the result exact for the running network.
  const int thin = S % 2 == 0 && S >= 40 ? 2 : 1, T = S / thin;
  Eigen::MatrixXd rhythm(T, L.rhythm);
  Eigen::VectorXd search_target(T);
  for (int k = 0; k < T; ++k) rhythm.row(k) = fine_rhythm.row(k * fine * thin), search_target[k] = target[k * thin];
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> best;
  double best_cost = std::numeric_limits<double>::infinity();
  const double scale = std::max(1e-6, rhythm.maxCoeff());  // couplings of a few units move a unit across its threshold
  // Each start runs a few iterations; the most promising then runs to convergence.
  auto solve = [&](std::vector<double>& p, std::vector<double>& w, int iterations) {
    ceres::Problem problem;
    problem.AddResidualBlock(new Residual(L, rhythm, period, search_target), nullptr, p.data(), w.data());
    auto bound = [&](double* block, int i, double lo, double hi) {
      problem.SetParameterLowerBound(block, i, lo);
      problem.SetParameterUpperBound(block, i, hi);
    };
    bound(p.data(), 0, 0.3, 40.0);
    for (int k = 0; k < units; ++k) {
      const int o = 1 + k * L.per_unit();
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
  // Every start's units are driven to follow parts of the target: unit 0 the half cycle around its
  // highest peak, unit 1 the rest (a second burst), each through the least-squares map from the rhythm
  // to that part's deviation from its mean (a negative coupling excites), scaled to a random input
  // range, the tonic input at the mean drive. Random couplings instead left more muscles in poor
  // local minima. A part that is flat gets random couplings.
  Eigen::MatrixXd centred(T, L.rhythm);
  for (int k = 0; k < T; ++k) centred.row(k) = rhythm.row(k) - mean_rhythm.transpose();
  const auto qr = centred.colPivHouseholderQr();
  Eigen::Index peak;
  search_target.maxCoeff(&peak);
  const double lowest = search_target.minCoeff(), target_range = search_target.maxCoeff() - lowest;
  std::vector<Eigen::VectorXd> follow(static_cast<std::size_t>(units));
  std::vector<double> follow_range(static_cast<std::size_t>(units), 0.0);
  for (int k = 0; k < units; ++k) {
    Eigen::VectorXd part = search_target;
    for (int i = 0; i < T; ++i) {
      double d = std::abs(static_cast<double>(i - peak)) / T;
      d = std::min(d, 1 - d);
      const bool near_peak = d < 0.25;
      if (units > 1 && near_peak != (k == 0)) part[i] = lowest;
    }
    if (part.maxCoeff() - lowest < 0.1 * target_range) continue;
    follow[static_cast<std::size_t>(k)] = -qr.solve((part.array() - part.mean()).matrix());
    const Eigen::VectorXd d = centred * follow[static_cast<std::size_t>(k)];
    follow_range[static_cast<std::size_t>(k)] = d.maxCoeff() - d.minCoeff();
  }
  for (int start = 0; start < starts; ++start) {
    std::vector<double> p(static_cast<std::size_t>(L.size()));
    p[0] = 1.0 + 9.0 * u(rng);
    for (int k = 0; k < units; ++k) {
      double* q = p.data() + 1 + k * L.per_unit();
      q[1] = 0.5 + 2.0 * u(rng);
      const double range = start == 0 ? 3.0 : 1.5 + 3.0 * u(rng);
      const bool follows = follow_range[static_cast<std::size_t>(k)] > 1e-9;
      double mean_drive = 0;
      for (int j = 0; j < L.rhythm; ++j) {
        q[2 + j] = follows ? std::clamp(follow[static_cast<std::size_t>(k)][j] * range / follow_range[static_cast<std::size_t>(k)], -20.0 / scale, 20.0 / scale)
                           : (6.0 * u(rng) - 3.0) / scale;
        mean_drive += q[2 + j] * mean_rhythm[j];
      }
      // Tonic input so that the unit crosses its threshold during the cycle: a unit that never fires
      // has no gradient to learn from.
      q[0] = mean_drive + (follows && start == 0 ? 0.0 : 0.3 * (2.0 * u(rng) - 1.0));
    }
    std::vector<double> w;
    exact_map(L, p, rhythm, period, search_target, w, nullptr, nullptr);  // the exact map starts the weights
    const double cost = solve(p, w, 8);
    if (cost < best_cost && exact_map(L, p, rhythm, period, search_target, w, nullptr, nullptr) < kMaxDrift) best_cost = cost, best = p, best_w = w;
  }
  PatternNeurons n;
  std::vector<double> w;
  if (best.empty()) {  // no start settles on one periodic response: the muscle keeps its mean
    best.assign(static_cast<std::size_t>(L.size()), 0.0);
    best[0] = 1.0;
    exact_map(L, best, fine_rhythm, period, target, w, &n, &fitted);
    n.weights.setZero();
    n.bias = std::max(0.0, target.mean());
    fitted.setConstant(n.bias);
    return n;
  }
  std::vector<double> converged = best;
  solve(converged, best_w, 30);
  // Converged neurons (the start's own if convergence lost periodicity), then the exact map, steady
  // start state and fit from the full-resolution rhythm: steps as fine as the running CPG's, so that
  // the network reproduces what `fitted` reports.
  if (exact_map(L, converged, rhythm, period, search_target, w, nullptr, nullptr) < kMaxDrift) best = converged;
  exact_map(L, best, fine_rhythm, period, target, w, &n, &fitted);
  return n;
}

}  // namespace cpgait
