// The reproduced gait: the fitted CPG drives the muscles on contact spheres fitted to the trial's feet.
#include <algorithm>
#include <cstdio>

#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/dynamics/contact.h"
#include "cpgait/gait/gain_margin.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/gait/tune_gait_controller.h"
#include "cpgait/progress.h"
#include "products.h"
#include "stage.h"
#include "output_files.h"

namespace cpgait::services {
namespace {

struct GaitStageOptions {
  std::optional<double> duration_s;
  // The defaults walk on their own (issue 22): tuned without residuals at knob 1, then a schedule
  // entry at 0.8 and 1.2. What they give on subject01 over seeds: docs/gait-tuning.md.
  bool residuals = false;
  bool phase_reference = true;
  int tune_evaluations = 600;
  std::optional<double> tune_horizon_s;  // absent: the walk's duration
  int tune_rounds = 3;
  int tune_population = 0;
  int tune_restarts = 3;
  double tune_budget_simulated_s = 0;
  int tune_seed = 1;
  double tune_rotation_limit_deg = 4.5;
  double tune_drift_weight = 0;  // at 1, longer walkers past the horizon, subject01's run slower (docs/gait-tuning.md)
  double tune_cycle_weight = 10;
  bool tune_entrainment = false;
  bool tune_swing_world = false, tune_stance_hold = false, tune_ankle = true;
  int foot_spheres = 5;
  std::vector<double> tune_steps_m, tune_pushes_N_s, tune_tolerances;
  std::vector<double> tune_step_at = {0.5};
  std::vector<double> tune_stop_at = {0.45};
  std::vector<double> speed_knobs = {0.8, 1.2};
  int schedule_evaluations = 600;
  double schedule_step_decay = 0.55;
  std::vector<double> check_tolerances = {5e-4, 2e-3};
  double gain_margin = 0;
  double tolerance = 1e-3, control_interval_s = 0.0025;
  std::string integrator = "ros34pw2";

  static const OptionFields<GaitStageOptions>& fields() {
    static const OptionFields<GaitStageOptions> f = [] {
      OptionFields<GaitStageOptions> f("Begins at the first heel strike, or earlier when the trial would end first; needs the cpg stage's fit.");
      f.optional_number("duration_s", &GaitStageOptions::duration_s, "s",
                             "simulated time; absent: with residuals two gait cycles, or what the trial has; without, the trial's length "
                             "and at least 10 s", NumberRange{0.0, 30.0, true})
            .boolean("residuals", &GaitStageOptions::residuals,
                     "true: pelvis residual actuators hold the rotations and soft springs the translations, for comparison (with "
                     "tune_evaluations 0, speed_knobs [], phase_reference false and foot_spheres 2: the stage's quick walk before "
                     "2026-11-29); false: the model walks on its own")
            .integer_choice("foot_spheres", &GaitStageOptions::foot_spheres, {2, 5},
                            "contact spheres per foot: 2 (heel, toes) or 5 (medial and lateral heel, first and fifth metatarsal heads, "
                            "toes: they resist the foot's roll, and subject01's controller tuned on them walked over ground steps)")
            .number("tolerance", &GaitStageOptions::tolerance, "",
                    "the integrator's error tolerance (relative and absolute) of the walk and of tuning's candidates without tune_tolerances",
                    NumberRange{1e-8, 0.1})
            .number("control_interval_s", &GaitStageOptions::control_interval_s, "s",
                    "the controller's interval: the CPG, reflexes and balance feedback are updated once per interval (also the "
                    "integrator's largest step and the motion's sample)",
                    NumberRange{1e-4, 0.01})
            .choice("integrator", &GaitStageOptions::integrator, {"ros34pw2", "rosenbrock", "linearly_implicit_euler"},
                    "ros34pw2 (third-order Rosenbrock-W), rosenbrock (ROS2: the walks before ros34pw2, with control_interval_s 0.001) or "
                    "linearly_implicit_euler (first order, one step per control interval; tolerance unused, check_tolerances in ros34pw2)")
            .boolean("phase_reference", &GaitStageOptions::phase_reference,
                     "the joint reflexes track the trial's cycle average at the CPG's phase (read from its rhythm neurons), not the trial at the simulation's time")
            .integer("tune_evaluations", &GaitStageOptions::tune_evaluations, 0, 5000,
                     "tune the controller to walk without residuals first: CMA-ES over the reflex and balance gains and the CPG's amplitude, this "
                     "many simulations in parallel (0: no tuning); the tuned CPG is written to _cpg_tuned.json and drives the gait")
            .optional_number("tune_horizon_s", &GaitStageOptions::tune_horizon_s, "s",
                             "simulated time per tuning candidate; absent: the walk's (duration_s). A tuned controller walks its "
                             "horizon, not necessarily beyond: shorter than the walk, a warning",
                             NumberRange{0.5, 30.0, true})
            .integer("tune_rounds", &GaitStageOptions::tune_rounds, 1, 10,
                     "CMA-ES restarts, each from the last best, their horizons rising evenly to tune_horizon_s")
            .integer("tune_population", &GaitStageOptions::tune_population, 0, 200,
                     "tuning: CMA-ES' candidates per generation, in every tuning of the stage: 0 (CMA-ES' own, 10 for the 9 searched "
                     "parameters) or at least 2")
            .integer("tune_restarts", &GaitStageOptions::tune_restarts, 0, 10,
                     "tuning: when a tuning's result falls before tune_horizon_s, CMA-ES again over the whole horizon, up to this many "
                     "times, each from the best so far with a round's share of the simulations (on top of the budget), until a walk "
                     "lasts the horizon (0: none)")
            .number("tune_budget_simulated_s", &GaitStageOptions::tune_budget_simulated_s, "s",
                    "tuning: a restart (tune_restarts) begins only while the simulated time all of the stage's tunings spent so far "
                    "plus the last round's again stays within this; simulated time, so the same inputs give the same search on any "
                    "machine (0: no bound; the summary's tuning reports each tuning's simulated_s)",
                    NumberRange{0.0, 1e6})
            .integer("tune_seed", &GaitStageOptions::tune_seed, 1, 1000000,
                     "tuning: CMA-ES' random seed in every tuning of the stage (each round and restart adds its index): another "
                     "seed, another search, when a tuned walk falls")
            .boolean("tune_entrainment", &GaitStageOptions::tune_entrainment,
                     "tuning: also search the CPG's entrainment by phase resetting, the share of its phase error made up at each "
                     "touchdown (0-1)")
            .boolean("tune_swing_world", &GaitStageOptions::tune_swing_world,
                     "tuning: also search the swing hip's world-frame share (SIMBICON's: the swing femur turned by the pelvis' "
                     "orientation error, so the foot lands headed as the trial's), from 1 where the CPG has no controller")
            .boolean("tune_stance_hold", &GaitStageOptions::tune_stance_hold,
                     "tuning: also search the stance-foot hold, the single-support hip moving its foot across the way against the "
                     "pelvis' sideways offset and speed")
            .boolean("tune_ankle", &GaitStageOptions::tune_ankle,
                     "tuning: also search the lateral ankle strategy, the single-support foot rolled onto its outer edge as the "
                     "pelvis moves out over it; only on a model with a joint that rolls each foot (gait2392's subtalar), as the "
                     "summary's tuning.ankle reports")
            .number("tune_rotation_limit_deg", &GaitStageOptions::tune_rotation_limit_deg, "deg",
                    "tuning: a walk whose worst rotation tracks the trial's cycle worse than this (RMS) costs as much as a fall (0: no bound)",
                    NumberRange{0.0, 90.0})
            .number("tune_drift_weight", &GaitStageOptions::tune_drift_weight, "1/rad",
                    "tuning: cost per rad of a walk's drift (its cycle-mean direction and pelvis yaw, middle cycle to last): walkers "
                    "that drift within the horizon fall soon after it (0: not counted; docs/gait-tuning.md)", NumberRange{0.0, 100.0})
            .number("tune_cycle_weight", &GaitStageOptions::tune_cycle_weight, "1/rad",
                    "tuning: cost per rad of a walk's cycle change, the RMS over its angles of its last cycle against the one "
                    "before: a walk on a stable limit cycle repeats itself (0: not counted; docs/gait-tuning.md)", NumberRange{0.0, 1000.0})
            .number_list("tune_steps_m", &GaitStageOptions::tune_steps_m, "m",
                         "tuning: ground steps (negative: down) each candidate also walks over, the edge under the pelvis at each of "
                         "tune_step_at; their walks count in the cost as the level one's does",
                         NumberRange{-0.2, 0.2}, 4)
            .number_list("tune_step_at", &GaitStageOptions::tune_step_at, "",
                         "tuning: where each ground step's edge reaches the pelvis, fractions of the horizon; each step is walked at "
                         "each (a controller tuned with its steps at one place is fitted to that place; empty: half the horizon)",
                         NumberRange{0.0, 0.99, true}, 8)
            .number_list("tune_stop_at", &GaitStageOptions::tune_stop_at, "",
                         "tuning: walk -> stand trials each candidate also walks, stopping at its stop phase after each of these "
                         "fractions of the horizon; only their falls count (empty: none)",
                         NumberRange{0.0, 0.99, true}, 4)
            .number_list("tune_pushes_N_s", &GaitStageOptions::tune_pushes_N_s, "N s",
                         "tuning: pushes each candidate also walks through, impulses at the pelvis over 0.1 s at half the horizon, "
                         "ground frame, three numbers each (x y z)",
                         NumberRange{-200.0, 200.0}, 12, 3)
            .number_list("tune_tolerances", &GaitStageOptions::tune_tolerances, "",
                         "tuning: integrator tolerances every candidate's walks are taken at (each one more simulation; linearly_implicit_euler: "
                         "in ros34pw2, besides its own), so the controller walks by its own stability (empty: tolerance alone)",
                         NumberRange{0.0, 0.1, true}, 4);
      add_walk_fields(f);
      return f;
    }();
    return f;
  }

  // The walks after the tuning: the speed knobs and their schedule, the tolerance check, the gain margin.
  static void add_walk_fields(OptionFields<GaitStageOptions>& f) {
    f.number_list("speed_knobs", &GaitStageOptions::speed_knobs, "",
                         "more walks, each as long as the first, at these CPG speed knobs (times the trial's cadence), the controller "
                         "scheduled for each knob where the CPG holds controllers tuned at several; their motions go to "
                         "_gait_speed_<knob>.mot, their strides and falls to the summary's speed_knobs",
                         NumberRange{0.2, 3.0, true}, 8)
            .integer("schedule_evaluations", &GaitStageOptions::schedule_evaluations, 0, 5000,
                     "after tuning, tune the controller again at each of speed_knobs with this many simulations, each from the "
                     "schedule at that knob so far: a gain schedule over the knob, stored in _cpg_tuned.json (0: one controller at every "
                     "knob). A knob where the schedule so far already walks tune_horizon_s, its stride within 5 % of cycle / knob, "
                     "keeps it unsearched")
            .number("schedule_step_decay", &GaitStageOptions::schedule_step_decay, "",
                    "the speed knobs' tunings: each round's and restart's initial CMA-ES step is the last's times this (1: 0.5 for all; "
                    "0.55: 0.5, 0.28, 0.15 over three rounds, refining the last round's walker)",
                    NumberRange{0.01, 1.0})
            .number_list("check_tolerances", &GaitStageOptions::check_tolerances, "",
                         "without residuals: the walk again at each of these integrator tolerances (the walk's own: tolerance), reported in "
                         "the summary's tolerance_check; a controller that walks at its own but falls at any of these walks by one "
                         "tolerance's integration error, not by its own stability (a warning; tune it with tune_tolerances). Empty: no check",
                         NumberRange{0.0, 0.1, true}, 4)
            .number("gain_margin", &GaitStageOptions::gain_margin, "",
                    "without residuals: each walk (this one and the speed knobs') again with each feedback gain (reflex, trunk, foot "
                    "placement) scaled in turn by this and by its inverse, 16 walks, how many still walk in its summary's gain_margin "
                    "(0: none; e.g. 0.8: subject01's default knob-0.8 controller keeps none, docs/gait-tuning.md)",
                    NumberRange{0.0, 0.999});
  }
};

// A number as printf's %g: a knob in file names ("0.8", "1.25"), a tolerance in messages ("0.0005").
std::string number_text(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

// How long a walk lasted and where it fell (null: it did not), as both kinds of further walk report it.
nlohmann::json walk_outcome(const ReproducedGaitResult& g) {
  return {{"simulated_s", g.time_s.empty() ? 0.0 : g.time_s.back()},
          {"fell_at_s", g.fell_at_s >= 0 ? nlohmann::json(g.fell_at_s) : nlohmann::json(nullptr)}, {"drift_rad", g.drift_rad}};
}

// The stage's walks after its tunings, each an equal part of the progress left.
struct WalksProgress {
  Progress* stage;
  double begin, each;
  ProgressShare next() {
    begin += each;
    return ProgressShare(stage, begin - each, begin);
  }
};

// The CPG's walks at other speed knobs, with the same options otherwise: each one's motion to
// _gait_speed_<knob>.mot, its strides and falls (the stride against the CPG's cycle / knob) returned.
nlohmann::json walk_at_speed_knobs(StageContext& trial, const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& feet,
                                   const ReproducedGaitOptions& options, const std::vector<double>& knobs, double margin_factor,
                                   WalksProgress& progress) {
  nlohmann::json runs = nlohmann::json::array();
  for (double knob : knobs) {
    const CpgModel driving = scheduled_at_speed(cpg, knob);
    ReproducedGaitOptions o = driving.controller ? with_controller(*driving.controller, options) : options;
    o.speed = knob;
    ProgressShare walk_progress = progress.next();
    const ReproducedGaitResult g = reproduce_gait(model, driving, reference, feet, o, &walk_progress);
    const std::string file = "_gait_speed_" + number_text(knob) + ".mot";
    trial.write(reproduced_gait_motion_table(model, g), file);
    nlohmann::json run = walk_outcome(g);
    run.update({{"speed_knob", knob}, {"file", trial.inputs.name + file},
                {"heel_strikes_s", {{"right", g.heel_strikes_r_s}, {"left", g.heel_strikes_l_s}}},
                {"stride_time_s", g.stride_time_s}, {"cycle_over_speed_s", cpg.cycle_s / (cpg.speed * knob)},
                {"stride_length_m", g.stride_length_m}, {"speed_m_s", g.speed_m_s}, {"distance_m", g.distance_m},
                {"worst_rotation_rms_deg", g.worst_rotation_rms_rad * 180 / M_PI}, {"amplitude", driving.amplitude}});
    run["contact_phases"] = reproduced_gait_contact_phases(g);
    if (margin_factor > 0 && !o.pelvis_residuals) run["gain_margin"] = gain_margin(model, driving, reference, feet, o, {margin_factor}).to_json();
    runs.push_back(run);
  }
  return runs;
}

// The walk again at each of `tolerances` (integrator tolerances), otherwise alike: how long each
// lasted and where it fell, and a warning in `summary` when the walk itself did not fall (`walked`)
// and any of these did.
nlohmann::json walk_at_tolerances(const Model& model, const CpgModel& cpg, const Storage& reference, const ContactSet& feet,
                                  const ReproducedGaitOptions& options, bool walked, const std::vector<double>& tolerances,
                                  nlohmann::json& summary, WalksProgress& progress) {
  nlohmann::json runs = nlohmann::json::array();
  std::vector<std::string> fell;
  for (double tolerance : tolerances) {
    ReproducedGaitOptions o = options;
    o.integrator = at_tolerance(o.integrator), o.integrator_tolerance = tolerance;
    ProgressShare walk_progress = progress.next();
    const ReproducedGaitResult g = reproduce_gait(model, cpg, reference, feet, o, &walk_progress);
    nlohmann::json run = walk_outcome(g);
    run["tolerance"] = tolerance;
    run["integrator"] = w_method_name(o.integrator);
    runs.push_back(run);
    if (g.fell_at_s >= 0) fell.push_back(number_text(tolerance) + " (at " + number_text(g.fell_at_s) + " s)");
  }
  if (walked && !fell.empty()) {
    std::string list;
    for (const std::string& f : fell) list += (list.empty() ? "" : ", ") + f;
    if (at_tolerance(options.integrator) != options.integrator)
      summary["warnings"].push_back("the walk falls with ros34pw2 at tolerance " + list +
                                    " but not in the linearly implicit Euler's steps: the controller walks partly by that method's "
                                    "integration error, not by its own stability alone");
    else
      summary["warnings"].push_back("the walk falls at integrator tolerance " + list + " but not at " + number_text(options.integrator_tolerance) +
                                    ": the controller walks by that tolerance's integration error, not by its own stability; tune it with "
                                    "tune_tolerances");
  }
  return runs;
}

// The stage's progress: the tunings take this share, each by its simulations (its restarts within
// it), the walks after them the rest.
constexpr double kTuningProgressShare = 0.95;

// The stage's tuning: the controller at knob 1, then (schedule_evaluations) a schedule entry at each
// speed knob; the tuned CPG to _cpg_tuned.json. Returns the summary's "tuning".
nlohmann::json tune_for_stage(StageContext& trial, const Model& model, CpgModel& driving, const Storage& reference, const ContactSet& feet,
                              const ReproducedGaitOptions& go, const GaitStageOptions& o, double horizon_s) {
  GaitTuningOptions to;
  to.evaluations = o.tune_evaluations;
  to.horizon_s = horizon_s;
  to.rounds = o.tune_rounds;
  to.population = o.tune_population;
  to.restarts = o.tune_restarts;
  to.restart_budget_s = o.tune_budget_simulated_s;
  to.seed = static_cast<unsigned long long>(o.tune_seed);
  to.worst_rotation_limit_deg = o.tune_rotation_limit_deg;
  to.drift_weight = o.tune_drift_weight;
  to.cycle_change_weight = o.tune_cycle_weight;
  to.tune_entrainment = o.tune_entrainment;
  to.tune_swing_world = o.tune_swing_world;
  to.tune_stance_hold = o.tune_stance_hold;
  to.tune_ankle = o.tune_ankle;
  to.foot_spheres = o.foot_spheres;
  to.ground_steps_m = o.tune_steps_m;
  if (!o.tune_step_at.empty()) to.ground_step_at = o.tune_step_at;
  to.stop_at = o.tune_stop_at;
  to.set_pushes(o.tune_pushes_N_s);  // the option's reader refused lists that are not triples
  to.integrator_tolerances = o.tune_tolerances;
  // The speed knobs' tunings: each from the schedule so far, refining it.
  GaitTuningOptions schedule_to = to;
  schedule_to.evaluations = o.schedule_evaluations;
  schedule_to.step_decay = o.schedule_step_decay;
  schedule_to.keep_walking_start_stride = 0.05;  // issue 22's stride target: at 1.2 subject01's search cost 340 s where its start walked
  // The speed knobs keep knob 1's ankle gains: searched again at 0.8, subject01's walked in 2 of 6 seeds, kept in 5 of 6 (docs/gait-tuning.md).
  schedule_to.tune_ankle = false;
  const std::vector<double> knobs = o.schedule_evaluations > 0 ? o.speed_knobs : std::vector<double>{};
  const double most_simulations = to.most_simulations() + static_cast<double>(schedule_to.most_simulations()) * static_cast<double>(knobs.size());
  double progress_begin = 0;
  auto progress_share = [&](const GaitTuningOptions& tuning) {
    const double end = progress_begin + kTuningProgressShare * tuning.most_simulations() / most_simulations;
    ProgressShare share(trial.progress, progress_begin, end);
    progress_begin = end;
    return share;
  };
  ProgressShare knob_1_progress = progress_share(to);
  const GaitTuningResult tuned = tune_gait_controller(model, driving, reference, feet, go, to, &knob_1_progress);
  driving = tuned.cpg;
  double spent_s = tuned.summary.simulated_s;
  nlohmann::json tuning = {{"simulations", tuned.summary.evaluations}, {"simulated_s", tuned.summary.simulated_s},
                           {"budget_simulated_s", o.tune_budget_simulated_s}, {"restarts_skipped", tuned.summary.restarts_skipped},
                           {"seconds", tuned.summary.seconds},
                           {"cost", {tuned.summary.start_cost, tuned.summary.cost}}, {"walked_s", {tuned.summary.start_walked_s, tuned.summary.walked_s}},
                           {"horizon_s", to.horizon_s}, {"population", o.tune_population}, {"seed", o.tune_seed}, {"restarts", tuned.summary.restarts}, {"rotation_limit_deg", to.worst_rotation_limit_deg}, {"drift_weight", to.drift_weight}, {"cycle_weight", to.cycle_change_weight}, {"entrainment", o.tune_entrainment}, {"swing_world", o.tune_swing_world}, {"stance_hold", o.tune_stance_hold}, {"ankle", tuned.summary.ankle_searched},
                           {"steps_m", o.tune_steps_m}, {"step_at", o.tune_step_at}, {"stop_at", o.tune_stop_at}, {"pushes_N_s", o.tune_pushes_N_s}, {"tolerances", o.tune_tolerances},
                           {"controller", driving.controller->to_json()}, {"amplitude", driving.amplitude}};
  for (double knob : knobs) {
    ReproducedGaitOptions at = go;
    at.speed = knob;
    schedule_to.spent_before_s = spent_s;
    ProgressShare knob_progress = progress_share(schedule_to);
    const GaitTuningResult k = tune_gait_controller(model, driving, reference, feet, at, schedule_to, &knob_progress);
    driving = k.cpg;
    spent_s += k.summary.simulated_s;
    tuning["schedule"].push_back({{"speed_knob", knob}, {"simulations", k.summary.evaluations}, {"simulated_s", k.summary.simulated_s},
                                  {"restarts_skipped", k.summary.restarts_skipped}, {"seconds", k.summary.seconds},
                                  {"walked_s", {k.summary.start_walked_s, k.summary.walked_s}}, {"restarts", k.summary.restarts}, {"step_decay", o.schedule_step_decay},
                                  {"kept_start", k.summary.kept_start}});
  }
  trial.write_text(json_text(driving.to_json(), 2) + "\n", "_cpg_tuned.json");
  return tuning;
}

class GaitStage final : public StageWithOptions<GaitStageOptions> {
 public:
  std::string name() const override { return "gait"; }
  std::string description() const override { return "reproduced gait: the CPG-driven muscles walk the model on contact spheres"; }
  std::vector<std::string> needs() const override { return {"cpg"}; }
  std::vector<std::string> writes() const override {
    return {"_gait.mot", "_gait_residuals.sto", "_gait_contact_forces.sto", "_gait.json", "_gait_reference.sto", "_cpg_tuned.json (when tuned)",
            "_gait_speed_<knob>.mot (speed_knobs)"};
  }
  std::vector<std::string> tables() const override { return {"_gait.mot", "_gait_residuals.sto"}; }

 protected:
  nlohmann::json execute(StageContext& trial, const GaitStageOptions& o) const override {
    const IkProduct& ik = *trial.products.find<IkProduct>();
    const FittedCpg* cpg = trial.products.find<FittedCpg>();
    if (!cpg) return {{"not_run", "no CPG was fitted in this run (see the cpg stage)"}};
    const Model& model = trial.model;
    ContactSet feet = default_foot_contacts(model, o.foot_spheres);
    if (feet.spheres.empty()) return {{"not_run", "the model has no calcn_/toes_ or foot_ bodies for contact spheres"}};
    // The simulation begins at the first heel strike whose phase lies in the trial, or earlier when
    // the trial would end first.
    const double cycle_s = cpg->model.cycle_s;
    double start = -1;
    for (double s : cpg->heel_strikes_s)
      if (!ik.time_s.empty() && s + cpg->model.phase_at_start * cycle_s >= ik.time_s.front()) {
        start = s;
        break;
      }
    const double available = ik.time_s.empty() ? 0 : ik.time_s.back() - ik.time_s.front();
    if (start < 0 || available < 0.5 * cycle_s)
      return {{"not_run", "the trial is shorter than half a gait cycle, or has no usable heel strike"}};

    // The IK's coordinates the walks follow, written to every digit (rad, m): from them `cpgait gait
    // --kinematics` replays the stage's walks to the bit (from the .mot's 12 digits in degrees, to ~1e-12).
    const Storage reference = make_storage("gait reference: the IK's coordinates", coordinate_names(model), ik.time_s, ik.q, false);
    trial.write(reference, "_gait_reference.sto", 17);
    const FootSphereFit fit = fit_foot_spheres_to_trial(model, feet, ik.time_s, ik.q);
    ReproducedGaitOptions go;
    go.start_time_s = start;
    go.duration_s = o.duration_s ? *o.duration_s : std::min(2 * cycle_s, available);
    go.pelvis_residuals = o.residuals;
    go.phase_indexed_reference = o.phase_reference;
    go.integrator_tolerance = o.tolerance;
    go.control_interval_s = o.control_interval_s;
    go.integrator = *w_method_named(o.integrator);  // the option's choices are the methods' names
    // A CPG fitted to CMC's excitations drives compliant-tendon muscles, as CMC's did (the seed method).
    go.compliant_tendons = trial.products.find<ComputedMuscleControlResult>() != nullptr;
    // Walking on its own, as long as the trial and at least 10 s (issue 22); held by residuals, which
    // need the trial's pelvis, what the trial has.
    const double own_walk_s = o.duration_s ? *o.duration_s : std::max(10.0, available);
    // A tuned controller walks without residuals, tuned by default to walk as long as it will: tuned to
    // 10 s, subject01's controllers fell 0.3-17 s after it over six seeds (docs/gait-tuning.md).
    // At most 30 s (the option's bound): a long trial's walk would make each candidate as long.
    const double horizon_s = o.tune_horizon_s.value_or(std::min(own_walk_s, 30.0));
    CpgModel driving = cpg->model;
    const nlohmann::json tuning =
        o.tune_evaluations > 0 ? tune_for_stage(trial, model, driving, reference, feet, go, o, horizon_s) : nlohmann::json();
    driving = scheduled_at_speed(driving, go.speed);  // a tuned CPG walks as it was tuned at this knob
    if (driving.controller) go = with_controller(*driving.controller, go);
    if (!go.pelvis_residuals) go.duration_s = own_walk_s;
    // The walks: this one, then the tolerance check's and the speed knobs'.
    const bool check = !go.pelvis_residuals && !o.check_tolerances.empty();
    const double walks = 1.0 + (check ? static_cast<double>(o.check_tolerances.size()) : 0.0) + static_cast<double>(o.speed_knobs.size());
    const double walks_begin = tuning.is_null() ? 0.0 : kTuningProgressShare;
    WalksProgress walks_progress{trial.progress, walks_begin, (1.0 - walks_begin) / walks};
    ProgressShare walk_progress = walks_progress.next();
    const ReproducedGaitResult g = reproduce_gait(model, driving, reference, feet, go, &walk_progress);
    trial.write(reproduced_gait_motion_table(model, g), "_gait.mot");
    trial.write(reproduced_gait_residual_table(g), "_gait_residuals.sto");
    trial.write(reproduced_gait_contact_table(g), "_gait_contact_forces.sto");
    nlohmann::json summary = reproduced_gait_metrics(model, g);
    summary["compliant_tendons"] = go.compliant_tendons;
    summary["pelvis_residuals"] = go.pelvis_residuals;
    summary["tolerance"] = go.integrator_tolerance;
    summary["control_interval_s"] = go.control_interval_s;
    summary["integrator"] = o.integrator;
    if (!tuning.is_null()) summary["tuning"] = tuning;
    if (!tuning.is_null() && horizon_s < go.duration_s - 1e-9)
      summary["warnings"].push_back("the controller was tuned to walk " + number_text(horizon_s) + " s (tune_horizon_s) and the walks last " +
                                    number_text(go.duration_s) + " s: a tuned controller walks its horizon, not necessarily beyond");
    nlohmann::json radius = nlohmann::json::object();
    for (std::size_t s = 0; s < feet.spheres.size(); ++s) radius[feet.spheres[s].name] = fit.radius_change_m[s] * 1000;
    summary["foot_fit"] = {{"depth_mm", fit.depth_m * 1000}, {"radius_change_mm", radius}, {"warnings", fit.warnings}};
    summary["belt_velocity_m_s"] = {feet.ground_velocity_m_s.x(), feet.ground_velocity_m_s.y(), feet.ground_velocity_m_s.z()};
    summary["cycle_over_speed_s"] = driving.cycle_s / (driving.speed * go.speed);
    if (o.gain_margin > 0 && !go.pelvis_residuals) summary["gain_margin"] = gain_margin(model, driving, reference, feet, go, {o.gain_margin}).to_json();
    if (check)
      summary["tolerance_check"] = walk_at_tolerances(model, driving, reference, feet, go, g.fell_at_s < 0, o.check_tolerances, summary, walks_progress);
    if (!o.speed_knobs.empty())
      summary["speed_knobs"] = walk_at_speed_knobs(trial, model, driving, reference, feet, go, o.speed_knobs, o.gain_margin, walks_progress);
    // A fall said in words: in the stage's one-line summary a fall is otherwise a number among hundreds.
    auto say_fall = [&](const nlohmann::json& walk, const std::string& which) {
      if (!walk["fell_at_s"].is_null())
        summary["warnings"].push_back(which + " fell at " + number_text(walk["fell_at_s"].get<double>()) + " s of " + number_text(go.duration_s) +
                                      " s (the pelvis below " + number_text(100 * go.fall_height_fraction) + " % of its starting height)");
    };
    say_fall(summary, "the walk");
    if (summary.contains("speed_knobs"))
      for (const nlohmann::json& run : summary["speed_knobs"]) say_fall(run, "the walk at speed knob " + number_text(run["speed_knob"].get<double>()));
    trial.write_text(json_text(summary, 2) + "\n", "_gait.json");
    return summary;
  }
};

}  // namespace

const Stage& gait_stage() {
  static const GaitStage stage;
  return stage;
}

}  // namespace cpgait::services
