#include "cpgait/gait/tune_gait_controller.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>

#include "cpgait/optim/cma_es.h"

namespace cpgait {
namespace {

// The searched parameters: log(kp / kp0), log(kv / kv0), and the amplitude's factor 1 + 0.3 tanh(p2)
// (a bounded change: the CPG's patterns are the trial's).
constexpr double kAmplitudeRange = 0.3;

struct Candidate {
  double kp, kv, amplitude_factor;
};

Candidate decode(const Eigen::VectorXd& p, const CpgController& start) {
  return {start.reflex_kp * std::exp(p[0]), start.reflex_kv * std::exp(p[1]), 1.0 + kAmplitudeRange * std::tanh(p[2])};
}

}  // namespace

GaitTuningResult tune_gait_controller(const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& contacts,
                                      const ReproducedGaitOptions& base, const GaitTuningOptions& t, Progress* progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const CpgController start = cpg.controller.value_or(CpgController{});
  std::vector<int> rotations;
  for (int c = 0; c < model.num_coordinates(); ++c)
    if (model.coordinates[c].is_angle()) rotations.push_back(c);
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  // The lowest-cost candidate's walk, kept as the candidates run: CMA-ES' best is one of them, so its
  // walk needs no second simulation for the summary.
  double best_cost = std::numeric_limits<double>::infinity(), best_walked = 0;
  // One candidate's simulation and score; walked receives the time it walked. The start's errors
  // (the inputs') propagate; a candidate's score as falling at once.
  auto score = [&](const Candidate& k, double* walked, bool rethrow) {
    ReproducedGaitOptions o = with_controller(CpgController{k.kp, k.kv, true, false}, base);
    o.duration_s = t.horizon_s;
    o.amplitude = base.amplitude * k.amplitude_factor;
    double cost = t.fall_weight;
    double time_walked = 0;
    try {
      const ReproducedGaitResult g = reproduce_gait(model, cpg, reference, contacts, o);
      time_walked = g.fell_at_s < 0 ? t.horizon_s : g.fell_at_s;
      double tracking = 0;
      for (int c : rotations) tracking += g.tracking_rms[c];
      tracking /= std::max<std::size_t>(1, rotations.size());
      const double effort = g.excitations.size() ? g.excitations.array().square().mean() : 0.0;
      cost = t.fall_weight * (t.horizon_s - time_walked) / t.horizon_s + t.tracking_weight * tracking + t.effort_weight * effort;
    } catch (const std::exception&) {
      if (rethrow) throw;
    }
    if (walked) *walked = time_walked;
    const int n = ++done;
    std::lock_guard<std::mutex> lock(progress_mutex);
    if (cost < best_cost) best_cost = cost, best_walked = time_walked;
    if (progress) progress->report(std::min(1.0, static_cast<double>(n) / (t.evaluations + 1)), "tuning the gait controller");
    return cost;
  };
  GaitTuningResult result;
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(3);
  result.summary.start_cost = score(decode(x0, start), &result.summary.start_walked_s, true);
  CmaEsOptions co;
  co.initial_sigma = 0.5;
  co.max_evaluations = t.evaluations;
  co.num_threads = t.num_threads;
  co.seed = t.seed;
  co.lower = Eigen::Vector3d(-3.0, -3.0, -3.0);  // gains from 1/20 of the start's ...
  co.upper = Eigen::Vector3d(4.0, 3.0, 3.0);     // ... to 55 (kp) and 20 (kv) times
  const CmaEsSummary s = cma_es([&](const Eigen::VectorXd& p) { return score(decode(p, start), nullptr, false); }, x0, co);
  Eigen::VectorXd best = x0;
  result.summary.cost = result.summary.start_cost;
  if (s.best_value < result.summary.start_cost) best = s.best_x, result.summary.cost = s.best_value;
  const Candidate k = decode(best, start);
  result.summary.walked_s = best != x0 ? best_walked : result.summary.start_walked_s;
  result.cpg = cpg;
  result.cpg.controller = CpgController{k.kp, k.kv, true, false};
  result.cpg.amplitude = cpg.amplitude * k.amplitude_factor;
  result.summary.evaluations = done.load();
  result.summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

std::string GaitTuningSummary::BriefReport() const {
  char buf[256];
  std::snprintf(buf, sizeof buf, "gait tuning: %d simulations in %.1f s; cost %.3f -> %.3f; walked %.2f s -> %.2f s before falling (or the horizon)",
                evaluations, seconds, start_cost, cost, start_walked_s, walked_s);
  return buf;
}

}  // namespace cpgait
