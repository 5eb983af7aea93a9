#pragma once
// Tuning the reproduced gait's controller to walk without residual actuators: CMA-ES (cma_es.h) over
// the joint reflex's gains, the CPG's amplitude and the balance feedback's gains (and optionally the
// CPG's entrainment at foot contact), each candidate a
// few simulations of the gait (reproduce_gait, no residuals, reflex targets from the trial's cycle at
// the CPG's phase: one per speed knob, ground step at each place and push, all at each integrator
// tolerance; walk -> stand trials, scored by their falls alone), each scored by
//   (horizon - time walked) / horizon * fall_weight + tracking_weight * (mean + worst rotation RMS, rad)
//   + effort_weight * mean squared excitation + stride_weight * |stride time / (cycle / speed) - 1|
//   + drift_weight * drift (rad) + cycle_change_weight * min(cycle change, its limit) (rad; a fall: the limit)
//   (+ fall_weight * the worst rotation's excess over a bound, relative to it, when one is set)
// and the candidate by their mean: the falls first, then the deviation from the trial's cycle, then
// effort. The simulations run in parallel; the starting controller (the CPG's, else the defaults) is
// evaluated first, so the result is never worse than it. The result goes into the CPG
// (CpgModel::controller, its amplitude), whose JSON then replays it. Tuned at a single speed knob
// other than the CPG's controller's, it starts from the CPG's schedule at that knob and is stored as
// the schedule's entry there (CpgModel::speed_schedule), the controller left as it was.
#include <Eigen/Core>
#include <algorithm>
#include <string>
#include <vector>

#include "cpgait/gait/reproduced_gait.h"

namespace cpgait {

struct GaitTuningOptions {
  int evaluations = 160;        // simulations CMA-ES may run (default 160)
  double horizon_s = 5.0;       // simulated time per candidate, s (default 5)
  double fall_weight = 10.0;    // cost of falling at once (default 10)
  // cost per rad of the rotations' mean tracking RMS plus their worst's (default 1). The worst's
  // because the target is per coordinate: on the mean alone a 15 s walk left hip_rotation_l at 6.1 deg.
  double tracking_weight = 1.0;
  double effort_weight = 0.1;   // cost per unit of mean squared excitation (default 0.1)
  // cost per unit of relative stride-time error against the CPG's cycle / speed (default 1): the
  // balance feedback's steps entrain the CPG, and untaxed they shortened subject01's stride by 11 %.
  double stride_weight = 1.0;
  // cost per rad of the walk's drift (ReproducedGaitResult::drift_rad) (default 0): the other terms
  // see only the horizon, and walkers that drift within it fall soon after it (docs/gait-tuning.md).
  double drift_weight = 0.0;
  // cost per rad of the walk's cycle change (ReproducedGaitResult::cycle_change_rad) (default 0).
  double cycle_change_weight = 0.0;
  // The cycle change counted at most, rad (default 0.25, past the 0.13-0.24 rad of walkers that fall
  // within 0.3 s of their horizon). A walk that falls counts it in full: its last cycle is the fall,
  // or before two cycles there is none, and either way the fall weight already scores it.
  double cycle_change_limit_rad = 0.25;
  // A bound on the worst rotation's tracking RMS (deg; 0: none, the default): beyond it a walk costs
  // fall_weight per bound's worth of excess, as much as falling at once. Tuned over ground steps
  // without it, subject01's hip_rotation_l drifted to 6.1 deg (measured).
  double worst_rotation_limit_deg = 0;
  // Speed knobs (times the gait options') each candidate walks at: its cost the mean of theirs, its
  // time walked the shortest (default: 1 alone).
  std::vector<double> speeds = {1.0};
  // Ground steps (m; negative: down) each candidate also walks over at the options' speed, the edge
  // under the pelvis at each of ground_step_at: their walks count as the speeds' do (default: none).
  std::vector<double> ground_steps_m;
  // Where the ground steps' edges reach the pelvis, fractions of the horizon (default: 0.5 alone).
  // A controller tuned with its steps at one place is fitted to that place (measured: test_gait.cpp).
  std::vector<double> ground_step_at = {0.5};
  // Pushes (impulses at the pelvis, N s, ground frame, over 0.1 s at half the horizon) each candidate
  // also walks through, counted as the ground steps are (default: none).
  std::vector<Eigen::Vector3d> pushes_N_s;
  // Walk -> stand trials each candidate also walks, on level ground at the options' speed: the walk
  // stops at its stop phase after each of these fractions of the horizon (ReproducedGaitOptions::
  // stop_time_s). Only their falls count (time walked before falling, as the others'): a stand has no
  // gait cycle to track or stride to time (default: none). Tuned without, a controller that walks may
  // fall once stopped (measured: test_so_gait2392.cpp). A trial whose level walk (at the same knob
  // and tolerance) fell before the stop is not simulated: it is that walk until the stop.
  std::vector<double> stop_at;
  // Integrator tolerances (ReproducedGaitOptions::integrator_tolerance) every walk above is taken at,
  // each one more simulation, counted as the speeds' are (default: none, the gait options' own alone;
  // with the linearly implicit Euler method, which has none, its own walk and one in ROS34PW2 at each);
  // a walk that fell at one is not taken again at the next, its fall counted there too. A controller
  // tuned at one tolerance may walk there by the integration error's accident alone (measured:
  // test_gait.cpp).
  std::vector<double> integrator_tolerances;
  // Sets pushes_N_s from x y z triples one after another; false (unchanged) unless a multiple of 3.
  bool set_pushes(const std::vector<double>& xyz_N_s);
  // CMA-ES runs this many times, each from the last one's best with a fresh step size, their horizons
  // rising evenly to horizon_s and the evaluations shared (default 1): short walks first, which are
  // cheap. On subject01 from the untuned start, 3 rounds to 15 s walked 11.4 s after 1,200
  // simulations and the whole 15 s after 2,000 (the pipeline, 589 s) - measured; a single round of
  // the same budget was not compared.
  int rounds = 1;
  // CMA-ES' initial step size in the searched parameters (1: a factor e in a reflex gain, a trunk
  // share of 1; default 0.5); smaller (0.15) refines a controller already tuned.
  double initial_step = 0.5;
  // Also search the entrainment (CpgController::entrainment, the share of the CPG's phase error made
  // up at each touchdown, from the start's, 0.25 per unit step, within [0, 1]; and the feet's
  // heel-strike phases it entrains to, 0.05 per unit) (default false: kept).
  bool tune_entrainment = false;
  // Also search the stance-foot hold's gains (simbicon_balance.h), from the start's (default false: kept).
  bool tune_stance_hold = false;
  // Also search the swing hip's world-frame share (SimbiconGains::swing_world), from the start's (default false: kept).
  bool tune_swing_world = false;
  // Also search the lateral ankle strategy's gains (SimbiconGains::ankle_d, ankle_v), from the start's,
  // or from 1 rad/m and 0.3 rad s/m where the CPG has no controller; only on a model with a joint to
  // roll each foot on (rolls_both_feet; GaitTuningSummary::ankle_searched) (default false: kept).
  bool tune_ankle = false;
  // The feet the walks stand on (`contacts`), recorded in the result's controller (CpgController::
  // foot_spheres): default_foot_contacts' spheres per foot, 0 for a contact file's (default 2). A
  // speed knob's entry is tuned on the controller's feet only (else std::invalid_argument).
  int foot_spheres = 2;
  // CMA-ES' population, candidates per generation (default 0: CMA-ES' own, 4 + 3 ln n: 10 for the 9
  // searched parameters). Larger explores more per generation in fewer generations.
  int population = 0;
  // When the rounds' result falls before the horizon: CMA-ES again over the whole horizon, up to this
  // many times, each from the best so far with the next seed and a round's share of the evaluations
  // (on top of `evaluations`), until a walk lasts the horizon (default 0: none).
  int restarts = 0;
  // A restart begins only while the simulated time spent so far (this tuning's plus spent_before_s)
  // and the last round's or restart's again would stay within this (simulated s; default 0: no
  // bound). Simulated time, not wall time, so that a search is the same on any machine; it bounds
  // the wall time where the simulations' speed is known (measured: docs/gait-tuning.md).
  double restart_budget_s = 0;
  double spent_before_s = 0;  // simulated s spent before this tuning, counted against restart_budget_s
  // Each round's (and restart's) initial step is the last's times this (default 1: initial_step for
  // all): later rounds, from a walker of a shorter horizon, refine it. Measured: docs/gait-tuning.md.
  double step_decay = 1.0;
  // Keep the start unsearched when it already walks every walk's whole horizon, each walk's stride
  // within this fraction of cycle / speed (default 0: always search; the gait stage's speed knobs: 0.05).
  double keep_walking_start_stride = 0;
  int num_threads = 0;          // simulations in parallel; 0: every core
  // The most simulations the tuning may run: the start's, each round's start over its horizon, the
  // rounds' and every restart's (its progress is reported against it).
  int most_simulations() const { return evaluations + restarts * (evaluations / std::max(1, rounds)) + rounds + 1; }
  unsigned long long seed = 1;
};

struct GaitTuningSummary {
  int evaluations = 0;
  double seconds = 0;
  double start_cost = 0, cost = 0;
  // The shortest of the walks taken, over the horizon, before falling (= horizon: none fell). A walk
  // that fell is not taken at the next tolerances, where it may fall sooner.
  double start_walked_s = 0, walked_s = 0;
  int restarts = 0;            // CMA-ES' restarts run (GaitTuningOptions::restarts)
  int restarts_skipped = 0;    // restarts the budget left out (GaitTuningOptions::restart_budget_s)
  double simulated_s = 0;      // simulated time over all of its simulations
  bool kept_start = false;     // the start walked and was kept unsearched (keep_walking_start_stride)
  bool ankle_searched = false; // tune_ankle, and the model has a joint to roll each foot on (rolls_both_feet)
  std::string BriefReport() const;
};

struct GaitTuningResult {
  CpgModel cpg;  // the input CPG with the tuned controller and amplitude
  GaitTuningSummary summary;
};

// `options`: the gait's other settings (start, feet, tendons...); its duration, residuals, reference
// and reflex gains are the tuner's.
GaitTuningResult tune_gait_controller(const Model& model, const CpgModel& cpg, const Storage& reference_coordinates,
                                      const ContactSet& contacts, const ReproducedGaitOptions& options,
                                      const GaitTuningOptions& tuning = {}, Progress* progress = nullptr);

}  // namespace cpgait
