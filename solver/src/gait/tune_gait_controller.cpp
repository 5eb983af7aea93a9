#include "cpgait/gait/tune_gait_controller.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "cpgait/gait/simbicon_balance.h"
#include "cpgait/gait/walk_measures.h"
#include "cpgait/optim/cma_es.h"

namespace cpgait {
namespace {

// The searched parameters: log(kp / kp0), log(kv / kv0), the amplitude's factor 1 + 0.3 tanh(p2) (a
// bounded change: the CPG's patterns are the trial's), then the balance gains (simbicon_balance.h) as
// the start's plus these steps per unit: trunk shares 1, foot placement 0.3 m/m and 0.1 s; with
// tune_stance_hold, the stance-foot hold's gains as the start's plus 0.3 m/m and 0.1 s per unit; with
// tune_swing_world, the swing hip's world-frame share as the start's plus 1 per unit; with tune_ankle,
// the lateral ankle strategy's gains as the start's plus 1 rad/m and 0.3 rad s/m per unit; with
// tune_entrainment, the entrainment share as the start's plus 0.25 per unit, within [0, 1], and the
// feet's heel-strike phases as the start's plus 0.05 per unit.
constexpr double kAmplitudeRange = 0.3;
constexpr int kParameters = 9, kStanceHoldParameters = 2, kAnkleParameters = 2, kEntrainmentParameters = 3;
const double kBalanceStep[6] = {1.0, 1.0, 0.3, 0.1, 0.3, 0.1};
constexpr double kEntrainmentStep = 0.25, kHeelStrikePhaseStep = 0.05, kAnkleStep[2] = {1.0, 0.3};

struct Candidate {
  CpgController controller;
  double amplitude_factor;
};

// p: the kParameters, then those t searches: the stance hold's, the swing hip's world share, the ankle
// strategy's and the entrainment's.
Candidate decode(const Eigen::VectorXd& p, const CpgController& start, const ReproducedGaitOptions& base, const GaitTuningOptions& t) {
  Candidate k{start, 1.0 + kAmplitudeRange * std::tanh(p[2])};
  k.controller.reflex_kp = start.reflex_kp * std::exp(p[0]);
  k.controller.reflex_kv = start.reflex_kv * std::exp(p[1]);
  double* balance[6] = {&k.controller.trunk_kp, &k.controller.trunk_kv, &k.controller.lateral_d,
                        &k.controller.lateral_v, &k.controller.sagittal_d, &k.controller.sagittal_v};
  for (int i = 0; i < 6; ++i) *balance[i] += kBalanceStep[i] * p[3 + i];
  Eigen::Index next = kParameters;
  if (t.tune_stance_hold) {
    k.controller.stance_lateral_d += kBalanceStep[2] * p[next++];
    k.controller.stance_lateral_v += kBalanceStep[3] * p[next++];
  }
  if (t.tune_swing_world) k.controller.swing_world += kBalanceStep[0] * p[next++];
  if (t.tune_ankle) {
    k.controller.ankle_d += kAnkleStep[0] * p[next++];
    k.controller.ankle_v += kAnkleStep[1] * p[next++];
  }
  if (t.tune_entrainment) {
    k.controller.entrainment = std::clamp(start.entrainment + kEntrainmentStep * p[next], 0.0, 1.0);
    k.controller.entrainment_phase_r = start.entrainment_phase_r + kHeelStrikePhaseStep * p[next + 1];
    k.controller.entrainment_phase_l = start.entrainment_phase_l + kHeelStrikePhaseStep * p[next + 2];
  }
  k.controller.phase_reference = true;
  k.controller.pelvis_residuals = false;
  k.controller.start_time_s = base.start_time_s;
  k.controller.begin_time_s = base.begin_time_s;
  record_simulation(base, k.controller);  // the candidates walk in the options' simulation
  return k;
}

// Where a search begins for a CPG without a controller: the default reflex and balance gains of the
// order the searches found on subject01 (trunk 2.2-3.2 / 2.8-3.6, foot placement across 0.3-0.7 m/m
// and 0.1-0.3 s, along 0.7-0.8 m/m and about 0 s), each a few of the search's steps from zero; the
// swing hip, where searched, in SIMBICON's world frame (share 1: from 0 the searches' walkers fell
// sooner after their horizon, docs/gait-tuning.md); the ankle strategy, where searched, at the gains
// that made two of four knob-1 walkers walk 30 s (1 rad/m, 0.3 rad s/m; docs/gait-tuning.md).
CpgController untuned_controller(const GaitTuningOptions& t) {
  CpgController k;
  k.swing_world = t.tune_swing_world ? 1.0 : 0.0;
  if (t.tune_ankle) k.ankle_d = 1.0, k.ankle_v = 0.3;
  k.trunk_kp = k.trunk_kv = 2.0;
  k.lateral_d = 0.3, k.lateral_v = 0.1;
  k.sagittal_d = 0.5, k.sagittal_v = 0.0;
  return k;
}

}  // namespace

bool GaitTuningOptions::set_pushes(const std::vector<double>& xyz_N_s) {
  if (xyz_N_s.size() % 3 != 0) return false;
  pushes_N_s.clear();
  for (std::size_t i = 0; i + 2 < xyz_N_s.size(); i += 3) pushes_N_s.emplace_back(xyz_N_s[i], xyz_N_s[i + 1], xyz_N_s[i + 2]);
  return true;
}

GaitTuningResult tune_gait_controller(const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& contacts,
                                      const ReproducedGaitOptions& options, const GaitTuningOptions& tuning, Progress* progress) {
  const auto t0 = std::chrono::steady_clock::now();
  // The ankle strategy is searched only where it has a joint to roll the feet on: elsewhere its gains
  // would be dimensions of the search that change no walk.
  GaitTuningOptions t = tuning;
  t.tune_ankle = t.tune_ankle && rolls_both_feet(model, simbicon_legs(model, contacts));
  // Every candidate, of every round's horizon, begins where a walk of the whole horizon would; the
  // controller keeps that beginning so a replay of any length is the same walk.
  ReproducedGaitOptions base = options;
  if (base.begin_time_s < 0 && reference.num_rows() > 0) {
    base.duration_s = t.horizon_s;
    base.begin_time_s = reproduced_gait_begin_s(cpg, reference.time()(0), reference.time()(reference.num_rows() - 1), base);
  }
  if (t.speeds.empty()) throw std::invalid_argument("tune_gait_controller: no speeds to walk at");
  if (t.rounds < 1) throw std::invalid_argument("tune_gait_controller: rounds must be at least 1");
  if (t.foot_spheres != 0 && t.foot_spheres != 2 && t.foot_spheres != 5)
    throw std::invalid_argument("tune_gait_controller: foot_spheres is 2 or 5 (spheres per foot) or 0 (a contact file)");
  if (!(t.initial_step > 0)) throw std::invalid_argument("tune_gait_controller: the initial step must be positive");
  if (!(t.step_decay > 0 && t.step_decay <= 1)) throw std::invalid_argument("tune_gait_controller: the step decay lies in (0, 1]");
  if (t.restarts < 0) throw std::invalid_argument("tune_gait_controller: restarts must not be negative");
  if (!(t.restart_budget_s >= 0 && t.spent_before_s >= 0))
    throw std::invalid_argument("tune_gait_controller: the restarts' budget and the time spent before must not be negative");
  const std::vector<int> rotations = walk_angles(model);
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  double simulated_s = 0;  // over every simulation so far, under progress_mutex
  // A single knob's tuning starts from the CPG's schedule there (scheduled_at_speed).
  const double knob = base.speed * (t.speeds.size() == 1 ? t.speeds.front() : 1.0);
  // Tuned at a single knob other than the CPG controller's: the result is the schedule's entry there.
  const bool schedule_entry = cpg.controller && t.speeds.size() == 1 && std::abs(knob - cpg.controller->speed) > 1e-9;
  if (schedule_entry && cpg.controller->foot_spheres != t.foot_spheres)
    throw std::invalid_argument("tune_gait_controller: a speed knob's entry is tuned on the controller's feet (" +
                                std::to_string(cpg.controller->foot_spheres) + " spheres per foot), not " + std::to_string(t.foot_spheres));
  if (schedule_entry) {
    // The schedule's entries share the controller's simulation (scheduled_at_speed keeps its).
    const CpgController& c = *cpg.controller;
    const ReproducedGaitOptions in_controllers = with_controller_simulation(c, base);
    if (in_controllers.control_interval_s != base.control_interval_s || in_controllers.integrator != base.integrator ||
        in_controllers.integrator_tolerance != base.integrator_tolerance)
      throw std::invalid_argument("tune_gait_controller: a speed knob's entry is tuned in the controller's simulation (interval " +
                                  std::to_string(c.control_interval_s) + " s, " + c.integrator + " at " + std::to_string(c.integrator_tolerance) +
                                  "), not another");
  }
  const CpgModel start = scheduled_at_speed(cpg, knob);
  CpgModel working = start;  // the best so far: its controller and amplitude
  working.controller = start.controller.value_or(untuned_controller(t));
  double horizon_s = t.horizon_s;
  // The lowest-cost candidate's walk in this round, kept as the candidates run: CMA-ES' best is one
  // of them, so its walk needs no second simulation.
  double best_cost = std::numeric_limits<double>::infinity(), best_walked = 0;
  // The walks each candidate takes: each speed knob on level ground, then each ground step and push,
  // each at every integrator tolerance in turn.
  struct Walk {
    double speed, step_m;
    Eigen::Vector3d push_N_s;
    double tolerance;
    double step_at = 0.5;  // the step's edge under the pelvis, a fraction of the horizon
    double stop_at = -1;   // a walk -> stand trial: the stop, a fraction of the horizon (< 0: none)
    WMethod integrator = WMethod::kRos34pw2;  // set with the tolerance
    bool same_ground_and_knob(const Walk& o) const {
      return speed == o.speed && step_m == o.step_m && push_N_s == o.push_N_s && step_at == o.step_at && stop_at == o.stop_at;
    }
    // The level walk a walk -> stand trial runs as, step for step, until its stop.
    bool is_level_walk_of(const Walk& stop) const {
      return stop_at < 0 && stop.stop_at >= 0 && speed == stop.speed && step_m == 0 && push_N_s.isZero() && tolerance == stop.tolerance &&
             integrator == stop.integrator;
    }
    // A level walk's first walk -> stand trial among walks (-1: none): it resumes from this walk's
    // state at its stop.
    int first_stop(const std::vector<Walk>& walks) const {
      for (std::size_t j = 0; j < walks.size(); ++j)
        if (is_level_walk_of(walks[j])) return static_cast<int>(j);
      return -1;
    }
  };
  // The integrations each walk is taken in: the options' own, or one per tolerance. A method without
  // a tolerance keeps its own walk and adds one per tolerance in the method at_tolerance gives.
  std::vector<std::pair<WMethod, double>> integrations;
  if (t.integrator_tolerances.empty() || at_tolerance(base.integrator) != base.integrator)
    integrations.emplace_back(base.integrator, base.integrator_tolerance);
  for (double tol : t.integrator_tolerances) {
    if (!(tol > 0)) throw std::invalid_argument("tune_gait_controller: integrator tolerances must be positive");
    integrations.emplace_back(at_tolerance(base.integrator), tol);
  }
  if (!t.ground_steps_m.empty() && t.ground_step_at.empty()) throw std::invalid_argument("tune_gait_controller: ground steps need a place (ground_step_at)");
  for (double at : t.ground_step_at)
    if (!(at > 0 && at < 1)) throw std::invalid_argument("tune_gait_controller: a ground step's place must lie inside the horizon (0 < ground_step_at < 1)");
  std::vector<Walk> walks;
  auto at_each_tolerance = [&](Walk w) {
    for (const auto& [method, tol] : integrations) w.integrator = method, w.tolerance = tol, walks.push_back(w);
  };
  for (double speed : t.speeds) at_each_tolerance({speed, 0.0, Eigen::Vector3d::Zero(), 0.0});
  for (double step : t.ground_steps_m)
    for (double at : t.ground_step_at) at_each_tolerance({1.0, step, Eigen::Vector3d::Zero(), 0.0, at});
  for (const Eigen::Vector3d& push : t.pushes_N_s) at_each_tolerance({1.0, 0.0, push, 0.0});
  for (double at : t.stop_at) {
    if (!(at > 0 && at < 1)) throw std::invalid_argument("tune_gait_controller: a stop must lie inside the horizon (0 < stop_at < 1)");
    at_each_tolerance({1.0, 0.0, Eigen::Vector3d::Zero(), 0.0, 0.5, at});
  }
  // One candidate's simulations and score; walked receives the shortest time it walked. The start's
  // errors (the inputs') propagate; a candidate's score as falling at once.
  auto score = [&](const Candidate& k, double* walked, bool rethrow, double* worst_stride_error = nullptr) {
    double cost = 0, time_walked = horizon_s, worst_stride = 0;
    double cost_here = 0, walked_here = horizon_s, simulated_here = 0;
    std::vector<double> fell_at_s(walks.size(), -1);  // each walk simulated so far: where it fell (< 0: it did not)
    // Per walk -> stand trial: its level walk's state at its stop, to resume from (the first trial of
    // each level walk only).
    std::vector<std::shared_ptr<const ReproducedGaitCheckpoint>> resume_at(walks.size());
    for (std::size_t i = 0; i < walks.size(); ++i) {
      const Walk& w = walks[i];
      // A walk -> stand trial is its level walk until the stop: where that one fell before the stop,
      // this one falls at the same step, and is not simulated again; else it goes on from the level
      // walk's state at the stop.
      if (w.stop_at >= 0) {
        double level_fell_at_s = -1;
        for (std::size_t j = 0; j < i; ++j)
          if (walks[j].is_level_walk_of(w) && fell_at_s[j] >= 0) level_fell_at_s = fell_at_s[j];
        if (level_fell_at_s >= 0 && level_fell_at_s < w.stop_at * horizon_s - 1e-9) {
          walked_here = level_fell_at_s;
          cost_here = t.fall_weight * (horizon_s - walked_here) / horizon_s;
          cost += cost_here / static_cast<double>(walks.size());
          time_walked = std::min(time_walked, walked_here);
          continue;
        }
      }
      // A walk that fell is not taken again at the next tolerance: it counts as falling there alike.
      // The tolerances are there to expose walks that stand by one tolerance's integration error; a
      // fall needs no second look, and the many falling candidates of a search walk once.
      if (i > 0 && walked_here < horizon_s && w.same_ground_and_knob(walks[i - 1])) {
        cost += cost_here / static_cast<double>(walks.size());
        continue;
      }
      ReproducedGaitOptions o = with_controller(k.controller, base);
      o.duration_s = horizon_s;
      o.amplitude = base.amplitude * k.amplitude_factor;
      o.speed = base.speed * w.speed;
      o.integrator = w.integrator, o.integrator_tolerance = w.tolerance;
      if (w.step_m != 0) o.ground_step_m = w.step_m, o.ground_step_time_s = w.step_at * horizon_s;
      if (w.push_N_s.norm() > 0) o.push_time_s = 0.5 * horizon_s, o.push_duration_s = 0.1, o.push_force_N = w.push_N_s / 0.1;
      if (w.stop_at >= 0) o.stop_time_s = w.stop_at * horizon_s;
      const int stop = w.first_stop(walks);
      if (stop >= 0) o.checkpoint_at_s = walks[static_cast<std::size_t>(stop)].stop_at * horizon_s;
      cost_here = t.fall_weight, walked_here = 0;
      try {
        const ReproducedGaitResult g = reproduce_gait(model, working, reference, contacts, o, nullptr, resume_at[i].get());
        if (!g.time_s.empty()) simulated_here += g.time_s.back() - g.resumed_at_s;
        fell_at_s[i] = g.fell_at_s;
        if (stop >= 0) resume_at[static_cast<std::size_t>(stop)] = g.checkpoint;
        walked_here = g.fell_at_s < 0 ? horizon_s : g.fell_at_s;
        cost_here = t.fall_weight * (horizon_s - walked_here) / horizon_s;
        if (w.stop_at < 0) {  // a walk: also how it tracks the trial's cycle, its effort and its stride
          double tracking = 0, worst = 0;
          for (int c : rotations) tracking += g.tracking_rms[c], worst = std::max(worst, g.tracking_rms[c]);
          tracking = tracking / static_cast<double>(std::max<std::size_t>(1, rotations.size())) + worst;
          const double effort = g.excitations.size() ? g.excitations.array().square().mean() : 0.0;
          // No two heel strikes of the CPG's foot: as far off as a stride twice the cycle.
          const double cycle_s = cpg.cycle_s / (cpg.speed * o.speed);
          const double stride_error = g.stride_time_s > 0 ? std::abs(g.stride_time_s / cycle_s - 1.0) : 1.0;
          // Unweighted, not counted at all: 0 x a drift that is not finite is not 0.
          const double cycle_change = g.fell_at_s >= 0 ? t.cycle_change_limit_rad : std::min(g.cycle_change_rad, t.cycle_change_limit_rad);
          const double drift = (t.drift_weight > 0 ? t.drift_weight * g.drift_rad : 0.0) +
                               (t.cycle_change_weight > 0 ? t.cycle_change_weight * cycle_change : 0.0);
          cost_here += t.tracking_weight * tracking + t.effort_weight * effort + t.stride_weight * stride_error + drift;
          worst_stride = std::max(worst_stride, stride_error);
          if (t.worst_rotation_limit_deg > 0)
            cost_here += t.fall_weight * std::max(0.0, worst * 180 / M_PI - t.worst_rotation_limit_deg) / t.worst_rotation_limit_deg;
        }
      } catch (const std::exception&) {
        if (rethrow) throw;
      }
      cost += cost_here / static_cast<double>(walks.size());
      time_walked = std::min(time_walked, walked_here);
    }
    if (walked) *walked = time_walked;
    if (worst_stride_error) *worst_stride_error = worst_stride;
    const int n = ++done;
    std::lock_guard<std::mutex> lock(progress_mutex);
    simulated_s += simulated_here;
    if (cost < best_cost) best_cost = cost, best_walked = time_walked;
    if (progress) progress->report(std::min(1.0, static_cast<double>(n) / t.most_simulations()), "tuning the gait controller");
    return cost;
  };
  GaitTuningResult result;
  result.summary.ankle_searched = t.tune_ankle;
  const int parameters = kParameters + (t.tune_stance_hold ? kStanceHoldParameters : 0) + (t.tune_swing_world ? 1 : 0) +
                         (t.tune_ankle ? kAnkleParameters : 0) + (t.tune_entrainment ? kEntrainmentParameters : 0);
  auto decode = [&](const Eigen::VectorXd& p, const CpgController& from, const ReproducedGaitOptions& b) {
    return cpgait::decode(p, from, b, t);
  };
  const Eigen::VectorXd x0 = Eigen::VectorXd::Zero(parameters);
  // The start, scored over the whole horizon for the summary.
  double start_stride_error = 0;
  result.summary.start_cost = score(decode(x0, *working.controller, base), &result.summary.start_walked_s, true, &start_stride_error);
  double cost = result.summary.start_cost, walked = result.summary.start_walked_s;
  result.summary.kept_start = t.keep_walking_start_stride > 0 && walked >= t.horizon_s && start_stride_error <= t.keep_walking_start_stride;
  if (result.summary.kept_start) working.controller = decode(x0, *working.controller, base).controller;  // as it was scored
  // The rounds over rising horizons, then the restarts over the whole horizon while the walk falls:
  // each a CMA-ES search from the best so far with the next seed, its initial step the last's times
  // step_decay, whose best replaces it when better.
  double step = t.initial_step;
  double last_round_s = 0;  // the simulated time of the last round or restart
  for (int round = 0; round < t.rounds + t.restarts && !result.summary.kept_start; ++round, step *= t.step_decay) {
    const bool restart = round >= t.rounds;
    if (restart && walked >= t.horizon_s) break;
    if (restart && t.restart_budget_s > 0 && t.spent_before_s + simulated_s + last_round_s > t.restart_budget_s) {
      result.summary.restarts_skipped = t.rounds + t.restarts - round;
      break;
    }
    const double round_begin_s = simulated_s;
    const double last_horizon_s = horizon_s;
    horizon_s = t.horizon_s * std::min(round + 1, t.rounds) / t.rounds;
    const CpgController from = *working.controller;
    double from_walked = walked;
    const double from_cost = horizon_s == last_horizon_s ? cost : score(decode(x0, from, base), &from_walked, true);
    best_cost = std::numeric_limits<double>::infinity();
    CmaEsOptions co;
    co.initial_sigma = step;
    co.max_evaluations = t.evaluations / t.rounds + (round + 1 == t.rounds ? t.evaluations % t.rounds : 0);
    co.num_threads = t.num_threads;
    co.population = t.population;
    co.seed = t.seed + static_cast<unsigned long long>(round);
    co.lower = Eigen::VectorXd::Constant(parameters, -3.0);  // gains from 1/20 of the start's ...
    co.upper = Eigen::VectorXd::Constant(parameters, 3.0);   // ... to 20 times; balance steps +-3
    co.upper[0] = 4.0;                                         // kp to 55 times
    const CmaEsSummary s = cma_es([&](const Eigen::VectorXd& p) { return score(decode(p, from, base), nullptr, false); }, x0, co);
    cost = from_cost, walked = from_walked;
    if (s.best_value < from_cost) {
      const Candidate k = decode(s.best_x, from, base);
      working.controller = k.controller;
      working.amplitude *= k.amplitude_factor;
      cost = s.best_value, walked = best_walked;
    }
    result.summary.restarts += restart;
    last_round_s = simulated_s - round_begin_s;
  }
  // Over the whole horizon the start may still score better than the rounds' result.
  if (cost > result.summary.start_cost) {
    working = start;
    working.controller = decode(x0, start.controller.value_or(untuned_controller(t)), base).controller;  // as it was scored
    cost = result.summary.start_cost, walked = result.summary.start_walked_s;
  }
  result.summary.cost = cost;
  result.summary.walked_s = walked;
  working.controller->speed = knob;
  working.controller->foot_spheres = t.foot_spheres;
  record_simulation(base, *working.controller);
  result.cpg = working;
  if (schedule_entry) {
    // The CPG as it was, its schedule's entry at this knob replaced.
    result.cpg = cpg;
    auto& schedule = result.cpg.speed_schedule;
    std::erase_if(schedule, [&](const ScheduledController& e) { return std::abs(e.controller.speed - knob) < 1e-9; });
    schedule.push_back({*working.controller, working.amplitude});
  }
  result.summary.evaluations = done.load();
  result.summary.simulated_s = simulated_s;
  result.summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

std::string GaitTuningSummary::BriefReport() const {
  char buf[320];
  std::snprintf(buf, sizeof buf, "gait tuning: %d simulations (%.0f s simulated) in %.1f s; cost %.3f -> %.3f; walked %.2f s -> %.2f s before falling (or the horizon)",
                evaluations, simulated_s, seconds, start_cost, cost, start_walked_s, walked_s);
  std::string report = buf;
  if (kept_start) report += "; the start walked and was kept";
  if (restarts > 0) report += "; " + std::to_string(restarts) + " restart(s)";
  if (restarts_skipped > 0) report += "; " + std::to_string(restarts_skipped) + " restart(s) left out by the budget";
  return report;
}

}  // namespace cpgait
