#include "cpgait/optim/cma_es.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <numeric>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

namespace cpgait {

std::string CmaEsSummary::BriefReport() const {
  char text[256];
  std::snprintf(text, sizeof text, "CMA-ES: best %.6g after %d evaluations (%d generations, %.3g s); stopped: %s", best_value,
                evaluations, generations, seconds, termination.c_str());
  return text;
}

CmaEsSummary cma_es(const CmaEsObjective& f, const Eigen::VectorXd& x0, const CmaEsOptions& o) {
  const auto start_time = std::chrono::steady_clock::now();
  const Eigen::Index n = x0.size();
  if (n < 1) throw std::invalid_argument("cma_es: x0 is empty");
  const bool bounded = o.lower.size() == n && o.upper.size() == n;
  if ((o.lower.size() != 0 || o.upper.size() != 0) && !bounded) throw std::invalid_argument("cma_es: bounds must have x0's size");
  if (o.population < 0 || o.population == 1) throw std::invalid_argument("cma_es: the population is 0 (the default) or at least 2 (it recombines the better half)");
  // Strategy parameters (the tutorial's Table 1).
  const int lambda = o.population > 0 ? o.population : 4 + static_cast<int>(std::floor(3.0 * std::log(static_cast<double>(n))));
  const int mu = lambda / 2;
  Eigen::VectorXd w(mu);
  for (int i = 0; i < mu; ++i) w[i] = std::log((lambda + 1.0) / 2.0) - std::log(i + 1.0);
  w /= w.sum();
  const double mu_eff = 1.0 / w.squaredNorm(), dn = static_cast<double>(n);
  const double c_c = (4.0 + mu_eff / dn) / (dn + 4.0 + 2.0 * mu_eff / dn);
  const double c_s = (mu_eff + 2.0) / (dn + mu_eff + 5.0);
  const double c_1 = 2.0 / ((dn + 1.3) * (dn + 1.3) + mu_eff);
  const double c_mu = std::min(1.0 - c_1, 2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((dn + 2.0) * (dn + 2.0) + mu_eff));
  const double d_s = 1.0 + 2.0 * std::max(0.0, std::sqrt((mu_eff - 1.0) / (dn + 1.0)) - 1.0) + c_s;
  const double chi_n = std::sqrt(dn) * (1.0 - 1.0 / (4.0 * dn) + 1.0 / (21.0 * dn * dn));  // E|N(0, I)|

  Eigen::VectorXd m = x0, p_s = Eigen::VectorXd::Zero(n), p_c = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd C = Eigen::MatrixXd::Identity(n, n), B = C;
  Eigen::VectorXd D = Eigen::VectorXd::Ones(n);  // sqrt of C's eigenvalues
  double sigma = o.initial_sigma, penalty = o.bound_penalty;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int threads = std::max(1, std::min(lambda, o.num_threads > 0 ? o.num_threads : static_cast<int>(std::thread::hardware_concurrency())));

  CmaEsSummary s;
  s.best_value = std::numeric_limits<double>::infinity();
  std::deque<double> recent_best;
  std::vector<Eigen::VectorXd> z(lambda), y(lambda), x(lambda), evaluated(lambda);
  std::vector<double> raw(lambda), fitness(lambda);
  std::vector<int> order(lambda);
  while (true) {
    // Sample (in one thread, so the seed alone fixes the search) ...
    for (int k = 0; k < lambda; ++k) {
      z[k].resize(n);
      for (Eigen::Index i = 0; i < n; ++i) z[k][i] = normal(rng);
      y[k] = B * D.cwiseProduct(z[k]);
      x[k] = m + sigma * y[k];
      evaluated[k] = bounded ? x[k].cwiseMax(o.lower).cwiseMin(o.upper) : x[k];
    }
    // ... evaluate in parallel.
    std::atomic<int> next{0};
    auto work = [&] {
      for (int k; (k = next++) < lambda;) raw[k] = f(evaluated[k]);
    };
    if (threads > 1) {
      std::vector<std::thread> pool;
      for (int t = 0; t < threads; ++t) pool.emplace_back(work);
      for (auto& t : pool) t.join();
    } else {
      work();
    }
    s.evaluations += lambda;
    ++s.generations;
    for (int k = 0; k < lambda; ++k) {
      if (std::isnan(raw[k])) raw[k] = std::numeric_limits<double>::infinity();  // a failed evaluation ranks last
      if (raw[k] < s.best_value) s.best_value = raw[k], s.best_x = evaluated[k];
    }
    if (bounded && penalty == 0) {
      // The first generation's spread of finite values sets the penalty's scale.
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (const double v : raw)
        if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
      penalty = 1e3 * std::max(hi > lo ? hi - lo : std::abs(hi), 1e-12);
    }
    for (int k = 0; k < lambda; ++k) fitness[k] = raw[k] + (bounded ? penalty * (x[k] - evaluated[k]).squaredNorm() : 0.0);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return fitness[a] < fitness[b]; });

    // Selection and recombination.
    Eigen::VectorXd y_w = Eigen::VectorXd::Zero(n), z_w = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < mu; ++i) y_w += w[i] * y[order[i]], z_w += w[i] * z[order[i]];
    m += sigma * y_w;
    // Step-size control: C^(-1/2) y_w = B z_w.
    p_s = (1.0 - c_s) * p_s + std::sqrt(c_s * (2.0 - c_s) * mu_eff) * (B * z_w);
    const double ps_norm = p_s.norm();
    const bool h_s = ps_norm / std::sqrt(1.0 - std::pow(1.0 - c_s, 2.0 * s.generations)) < (1.4 + 2.0 / (dn + 1.0)) * chi_n;
    // Covariance: rank-one (evolution path) and rank-mu updates.
    p_c = (1.0 - c_c) * p_c + (h_s ? std::sqrt(c_c * (2.0 - c_c) * mu_eff) : 0.0) * y_w;
    Eigen::MatrixXd rank_mu = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i < mu; ++i) rank_mu.noalias() += w[i] * y[order[i]] * y[order[i]].transpose();
    C = (1.0 - c_1 - c_mu) * C + c_1 * (p_c * p_c.transpose() + (h_s ? 0.0 : c_c * (2.0 - c_c)) * C) + c_mu * rank_mu;
    sigma *= std::exp(std::min(1.0, (c_s / d_s) * (ps_norm / chi_n - 1.0)));
    C = 0.5 * (C + C.transpose());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
    B = eig.eigenvectors();
    D = eig.eigenvalues().cwiseMax(1e-300).cwiseSqrt();

    // Termination.
    recent_best.push_back(raw[order[0]]);
    if (recent_best.size() > 10) recent_best.pop_front();
    const auto [lo, hi] = std::minmax_element(recent_best.begin(), recent_best.end());
    const double generation_spread = fitness[order[lambda - 1]] - fitness[order[0]];
    if (s.best_value <= o.target_value) s.termination = "target value reached";
    else if (recent_best.size() == 10 && *hi - *lo < o.function_tolerance && generation_spread < o.function_tolerance)
      s.termination = "function tolerance";
    else if (sigma * std::sqrt(C.diagonal().maxCoeff()) < o.x_tolerance) s.termination = "x tolerance";
    else if (s.evaluations + lambda > o.max_evaluations) s.termination = "evaluation budget";
    else if (!std::isfinite(sigma) || D.maxCoeff() > 1e14 * D.minCoeff()) s.termination = "ill-conditioned covariance";
    if (!s.termination.empty()) break;
  }
  s.final_sigma = sigma;
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  return s;
}

}  // namespace cpgait
