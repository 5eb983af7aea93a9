// cpg fit / cpg run: a Matsuoka CPG fitted to a trial's muscle patterns, and run with its knobs.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "commands.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/capture/json_input.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/gait/gain_margin.h"
#include "cpgait/gait/tune_gait_controller.h"
#include "cpgait/kinematics/gait_events.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

std::vector<double> column_of(const Storage& s, int c) { return std::vector<double>(s.data.col(c).data(), s.data.col(c).data() + s.num_rows()); }

CpgModel read_cpg_model(const std::string& path) {
  return CpgModel::from_json(parse_json_input(text::read_file(path), path), path);
}

Storage cpg_table(const std::string& name, const std::vector<std::string>& labels, const std::vector<double>& time, const Eigen::MatrixXd& values) {
  return make_storage(name, labels, time, values, false);
}

// cpg fit
void add_cpg_fit_command(CLI::App& cpg) {
  auto* fit = cpg.add_subcommand(
      "fit",
      "Fit a CPG to muscle activations or excitations (.sto: static optimization's _activation.sto, CMC's\n"
      "_controls.sto). Gait cycles run from heel strike to heel strike: give the times (--cycle-starts, s)\n"
      "or a GRF .mot and its vertical-force column of one foot. Writes the model JSON (cpgait.cpg/1: time\n"
      "constants in s, the output map, knobs, feedback gains) and <output>_target.sto / <output>_fitted.sto\n"
      "(the cycle-averaged patterns and the CPG's, over one cycle); prints R^2 per muscle.");
  struct FitArgs {
    std::string patterns, grf, force_column = "ground_force_vy", model, out;
    std::vector<double> starts;
    CpgFitOptions o;
    double threshold_N = 20;
  };
  auto f = std::make_shared<FitArgs>();
  fit->add_option("--patterns", f->patterns, "activations or excitations (.sto), one column per muscle")->required()->check(CLI::ExistingFile);
  fit->add_option("--cycle-starts", f->starts, "heel-strike times (s), at least two");
  fit->add_option("--grf", f->grf, "ground reaction forces (.mot) to find heel strikes in")->check(CLI::ExistingFile);
  fit->add_option("--force-column", f->force_column, "the foot's vertical force column (N)")->capture_default_str();
  fit->add_option("--contact-threshold", f->threshold_N, "force (N) whose upward crossing is a heel strike")->capture_default_str();
  fit->add_option("--model", f->model, "OpenSim model: only its muscles' columns are fitted (default: every column)")->check(CLI::ExistingFile);
  fit->add_option("--pairs", f->o.pairs, "rhythm-layer oscillator pairs")->capture_default_str();
  fit->add_option("--pattern-units", f->o.pattern_units, "pattern neurons per active muscle (0: muscles read the rhythm layer)")
      ->check(CLI::Range(0, 2))->capture_default_str();
  fit->add_option("--starts", f->o.starts, "rhythm-layer optimisation starts")->capture_default_str();
  fit->add_option("-o,--output", f->out, "model JSON to write")->required();
  fit->callback([f] {
    const Storage s = read_storage(f->patterns);
    std::vector<std::string> names;
    std::vector<int> cols;
    std::vector<std::string> muscles;
    if (!f->model.empty())
      for (const auto& m : read_osim(f->model).model.muscles) muscles.push_back(m.name);
    for (int c = 1; c < s.num_columns(); ++c)
      if (muscles.empty() || std::find(muscles.begin(), muscles.end(), s.labels[static_cast<std::size_t>(c)]) != muscles.end())
        names.push_back(s.labels[static_cast<std::size_t>(c)]), cols.push_back(c);
    if (cols.empty()) throw InputError(f->patterns, 0, "labels", "no muscle columns to fit");
    std::vector<double> starts = f->starts;
    if (starts.empty()) {
      if (f->grf.empty()) throw InputError("cpgait cpg fit", 0, "cycle_starts", "give --cycle-starts or --grf to find the gait cycles");
      const Storage g = read_storage(f->grf);
      const int c = g.column(f->force_column);
      if (c < 0) throw InputError(f->grf, 0, f->force_column, "no such column in the GRF file");
      starts = contact_onsets(g.time(), g.data.col(c), f->threshold_N);
    }
    Eigen::MatrixXd patterns(s.num_rows(), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t k = 0; k < cols.size(); ++k) patterns.col(static_cast<Eigen::Index>(k)) = s.data.col(cols[k]);
    const std::vector<double> time = column_of(s, 0);
    const Eigen::MatrixXd cycle = cycle_average(time, patterns, starts, f->o.phase_samples);
    int cycles = 0;
    const double cycle_s = mean_cycle_duration(time, starts, &cycles);
    const CpgFitResult r = fit_cpg(cycle, cycle_s, names, f->o);
    write_text_atomic(f->out, json_text(r.model.to_json(), 2) + "\n");
    const std::string stem = (fs::path(f->out).parent_path() / fs::path(f->out).stem()).string();
    std::vector<double> phase_time;
    for (int k = 0; k < cycle.rows(); ++k) phase_time.push_back(cycle_s * k / static_cast<double>(cycle.rows()));
    write_storage_atomic(cpg_table("cycle-averaged target patterns", names, phase_time, r.target), stem + "_target.sto");
    write_storage_atomic(cpg_table("CPG-fitted patterns", names, phase_time, r.fitted), stem + "_fitted.sto");
    std::printf("%d gait cycle(s), mean %.3f s; %s\n", cycles, cycle_s, r.summary.BriefReport().c_str());
    for (std::size_t k = 0; k < names.size(); ++k)
      std::printf("  %-16s peak %.3f  R^2 %.3f\n", names[k].c_str(), r.target.col(static_cast<Eigen::Index>(k)).maxCoeff(),
                  r.summary.r_squared[static_cast<Eigen::Index>(k)]);
    std::printf("wrote %s, %s_target.sto, %s_fitted.sto\n", f->out.c_str(), stem.c_str(), stem.c_str());
  });

}

// cpg run
void add_cpg_run_command(CLI::App& cpg) {
  auto* run = cpg.add_subcommand(
      "run",
      "Run a fitted CPG (model JSON from `cpg fit`): writes <output>_neurons.sto (every neuron's output y)\n"
      "and <output>_excitations.sto (each muscle's excitation, 0-1), sampled every --dt seconds. Knobs:\n"
      "--speed scales the cycle frequency, --amplitude the excitations; --to B.json with --transition t0 t1\n"
      "blends smoothly into another CPG (same structure), e.g. walk -> faster walk, walk -> stand.");
  struct RunArgs {
    std::string model, to, out;
    double duration_s = 5, dt_s = 0.001;
    std::optional<double> speed, amplitude;
    std::vector<double> transition;
  };
  auto a = std::make_shared<RunArgs>();
  run->add_option("--model", a->model, "CPG model JSON")->required()->check(CLI::ExistingFile);
  run->add_option("--duration", a->duration_s, "seconds to run")->check(CLI::Range(1e-3, 3600.0))->capture_default_str();
  run->add_option("--dt", a->dt_s, "step and sampling interval, s")->check(CLI::Range(1e-5, 0.05))->capture_default_str();
  run->add_option("--speed", a->speed, "cycle frequency factor (1: as fitted)")->check(CLI::Range(0.1, 10.0));
  run->add_option("--amplitude", a->amplitude, "excitation factor (0: silent)")->check(CLI::Range(0.0, 10.0));
  run->add_option("--to", a->to, "second CPG model to blend into")->check(CLI::ExistingFile);
  run->add_option("--transition", a->transition, "blend window t0 t1 (s) for --to")->expected(2);
  run->add_option("-o,--output", a->out, "output prefix")->required();
  run->callback([a] {
    CpgModel m = read_cpg_model(a->model);
    if (a->speed) m.speed = *a->speed;
    if (a->amplitude) m.amplitude = *a->amplitude;
    CpgRun r;
    if (!a->to.empty()) {
      if (a->transition.size() != 2 || !(a->transition[0] < a->transition[1]))
        throw InputError("cpgait cpg run", 0, "transition", "--to needs --transition t0 t1 with t0 < t1");
      r = run_cpg_transition(m, read_cpg_model(a->to), a->transition[0], a->transition[1], a->duration_s, a->dt_s);
    } else {
      r = run_cpg(m, a->duration_s, a->dt_s);
    }
    std::vector<std::string> neurons;
    for (int i = 0; i < m.network.size(); ++i) neurons.push_back("y" + std::to_string(i));
    if (!fs::path(a->out).parent_path().empty()) ensure_directory(fs::path(a->out).parent_path().string());
    write_storage_atomic(cpg_table("CPG neuron outputs", neurons, r.time_s, r.neurons), a->out + "_neurons.sto");
    write_storage_atomic(cpg_table("CPG muscle excitations", m.muscle_names, r.time_s, r.excitations), a->out + "_excitations.sto");
    std::printf("ran %.3f s (%zu steps, cycle %.3f s at speed %.2f); wrote %s_neurons.sto and %s_excitations.sto\n", a->duration_s,
                r.time_s.size(), m.cycle_s / m.speed, m.speed, a->out.c_str(), a->out.c_str());
  });
}

struct GaitArgs {
  std::string model, generic_model, cpg, kinematics, contacts, out;
  double start = -1;
  double entrainment = -1;  // < 0: the controller's
  std::vector<double> entrainment_phases;  // right, left; empty: the controller's
  ReproducedGaitOptions options;
  bool no_residuals = false, no_foot_fit = false;
  int foot_spheres = 0;  // 0: the CPG controller's feet, else 2
  GaitTuningOptions tuning;
  int tune = 0;
  double gain_margin = 0;  // 0: no gain-margin walks
  std::vector<double> push_force_N;
  std::vector<double> tune_pushes_N_s;  // x y z per push
  // --tolerance, --control-interval, --integrator: given, they win over the simulation a controller was tuned in.
  const CLI::Option *tolerance_option = nullptr, *control_interval_option = nullptr, *integrator_option = nullptr;
};

// --integrator's names (w_method_name's).
std::map<std::string, WMethod> w_methods_by_name() {
  std::map<std::string, WMethod> names;
  for (WMethod w : {WMethod::kRos34pw2, WMethod::kRos2, WMethod::kLinearlyImplicitEuler}) names[w_method_name(w)] = w;
  return names;
}

// --tune: the CPG with its controller tuned, written to <out>_cpg_tuned.json.
CpgModel tune_in_cli(const GaitArgs& g, const Model& model, const CpgModel& cpg, const Storage& kin, const ContactSet& contacts,
                     const ReproducedGaitOptions& o, int foot_spheres) {
  GaitTuningOptions to = g.tuning;
  to.evaluations = g.tune;
  to.foot_spheres = foot_spheres;
  if (!to.set_pushes(g.tune_pushes_N_s)) throw InputError("--tune-pushes", 0, "tune-pushes", "expected three numbers (x y z) per push");
  const GaitTuningResult tuned = tune_gait_controller(model, cpg, kin, contacts, o, to);
  write_text_atomic(g.out + "_cpg_tuned.json", json_text(tuned.cpg.to_json(), 2) + "\n");
  std::printf("%s\nwrote %s_cpg_tuned.json (reflex %.1f / %.2f, amplitude %.3f)\n", tuned.summary.BriefReport().c_str(), g.out.c_str(),
              tuned.cpg.controller->reflex_kp, tuned.cpg.controller->reflex_kv, tuned.cpg.amplitude);
  if (to.tune_ankle && !tuned.summary.ankle_searched)
    print_warnings({"--tune-ankle: the model has no rotation below each hip within 60 deg of the pelvis' heading (as gait2392's subtalar) to roll "
                    "the stance foot on, so the ankle strategy's gains were not searched"});
  if (o.duration_s > to.horizon_s + 1e-9) {
    char w[200];
    std::snprintf(w, sizeof w, "tuned to walk %g s (--tune-horizon) and walking %g s (--duration): a tuned controller walks its horizon, not necessarily beyond",
                  to.horizon_s, o.duration_s);
    print_warnings({w});
  }
  return tuned.cpg;
}

void run_gait(const GaitArgs& g) {
  const OsimReadResult mr = read_muscle_model(g.model, g.generic_model);
  const Model& model = mr.model;
  const CpgModel cpg = read_cpg_model(g.cpg);
  const Storage kin = read_storage(g.kinematics);
  const std::string contacts_text = g.contacts.empty() ? std::string() : text::read_file(g.contacts);
  // Without a contact file: the spheres asked for, else those the CPG's controller was tuned on.
  const int controller_feet = cpg.controller ? cpg.controller->foot_spheres : 2;
  if (g.contacts.empty() && g.foot_spheres == 0 && controller_feet == 0)
    throw InputError(g.cpg, 0, "controller.foot_spheres", "the CPG's controller was tuned on a contact file: give it with --contacts");
  const int foot_spheres = g.contacts.empty() ? (g.foot_spheres > 0 ? g.foot_spheres : controller_feet) : 0;
  ContactSet contacts = g.contacts.empty() ? default_foot_contacts(model, foot_spheres) : parse_contact_set_json(contacts_text, g.contacts, model);
  // A contact file that sets no ground gets the default feet's: under the recorded feet, spheres fitted.
  const nlohmann::json contacts_json = g.contacts.empty() ? nlohmann::json::object() : parse_json_input(contacts_text, g.contacts);
  const bool ground_given = contacts_json.contains("ground_height_m") || contacts_json.contains("ground_velocity_m_s");
  if (contacts.spheres.empty())
    throw InputError(g.model, 0, "contacts", "the model has no calcn_/toes_ or foot_ bodies for default contact spheres: give --contacts");
  ReproducedGaitOptions o = g.options;
  // The simulation the CPG's controller was tuned in, for its tuning below and its walk, unless given here.
  auto given = [](const CLI::Option* option) { return option && option->count() > 0; };
  auto simulation_given_here = [&](ReproducedGaitOptions& x) {
    if (given(g.tolerance_option)) x.integrator_tolerance = g.options.integrator_tolerance;
    if (given(g.control_interval_option)) x.control_interval_s = g.options.control_interval_s;
    if (given(g.integrator_option)) x.integrator = g.options.integrator;
  };
  if (cpg.controller) {
    o = with_controller_simulation(*cpg.controller, o);
    simulation_given_here(o);
  }
  o.pelvis_residuals = !g.no_residuals;
  if (!g.push_force_N.empty()) o.push_force_N = Eigen::Vector3d(g.push_force_N[0], g.push_force_N[1], g.push_force_N[2]);
  const CoordinateTrajectories k = coordinate_trajectories(model, kin, {});
  if (g.start >= 0) {
    o.start_time_s = g.start;
  } else if (cpg.controller && cpg.controller->start_time_s >= 0) {
    o.start_time_s = cpg.controller->start_time_s;
    std::printf("start: the heel strike at %.3f s the CPG's controller was tuned from\n", o.start_time_s);
  } else {
    const std::string foot = model.body_index("calcn_r") >= 0 ? "calcn_r" : "foot_r";
    const auto strikes = heel_strikes_zeni(model, k.time_s, k.q, foot);
    if (strikes.empty()) throw InputError(g.kinematics, 0, "start", "no heel strike of " + foot + " found: give --start");
    o.start_time_s = strikes.front();
    std::printf("start: heel strike of %s at %.3f s (Zeni)\n", foot.c_str(), o.start_time_s);
  }
  // The ground under the recorded feet (as CMC places it), the spheres fitted to the trial's feet: on
  // the file's own rows, as the pipeline's gait stage fits them to its IK's, so that a controller the
  // stage tuned replays on its feet (on rows resampled from rounded times the belt differed by 2e-5).
  if (!ground_given) {
    if (g.no_foot_fit) {
      place_ground_under_feet(model, contacts, k.recorded_time_s, k.q_recorded);
    } else {
      const FootSphereFit fit = fit_foot_spheres_to_trial(model, contacts, k.recorded_time_s, k.q_recorded);
      print_warnings(fit.warnings);
      std::printf("feet fitted to the trial: depth %.1f mm (mean sphere force %.0f N); radius changes", fit.depth_m * 1000, fit.mean_force_N);
      for (std::size_t s = 0; s < contacts.spheres.size(); ++s)
        std::printf(" %s %+.1f mm", contacts.spheres[s].name.c_str(), fit.radius_change_m[s] * 1000);
      std::printf("\n");
    }
    std::printf("ground under the recorded feet: y = %.4f m, moving at (%.2f, %.2f, %.2f) m/s%s\n", contacts.ground_height_m,
                contacts.ground_velocity_m_s.x(), contacts.ground_velocity_m_s.y(), contacts.ground_velocity_m_s.z(),
                contacts.ground_velocity_m_s.norm() > 0 ? " (a treadmill)" : "");
  }
  if (!fs::path(g.out).parent_path().empty()) ensure_directory(fs::path(g.out).parent_path().string());
  CpgModel driving = g.tune > 0 ? tune_in_cli(g, model, cpg, kin, contacts, o, foot_spheres) : cpg;
  if (!driving.speed_schedule.empty()) {
    driving = scheduled_at_speed(driving, o.speed);
    std::printf("controller scheduled at speed knob %.3f from the %zu tuned knobs (amplitude %.3f)\n", o.speed,
                driving.speed_schedule.size() + 1, driving.amplitude);
  }
  if (driving.controller) {
    o = with_controller(*driving.controller, o);
    simulation_given_here(o);
    if (g.start >= 0) o.start_time_s = g.start;  // given: they win over the controller's
    if (g.options.begin_time_s >= 0) o.begin_time_s = g.options.begin_time_s;
    std::printf("controller from the CPG: reflex %.1f / %.2f, %s, %s residuals; updated every %g ms, %s at tolerance %g\n", o.reflex_kp,
                o.reflex_kv, o.phase_indexed_reference ? "reference by phase" : "reference by time", o.pelvis_residuals ? "with" : "without",
                o.control_interval_s * 1000, w_method_name(o.integrator).c_str(), o.integrator_tolerance);
  }
  if (g.entrainment >= 0) o.entrainment.share = g.entrainment;  // given: they win over the controller's
  if (g.entrainment_phases.size() == 2) o.entrainment.phase_r = g.entrainment_phases[0], o.entrainment.phase_l = g.entrainment_phases[1];
  const ReproducedGaitResult r = reproduce_gait(model, driving, kin, contacts, o);
  print_warnings(r.warnings);
  write_storage_atomic(reproduced_gait_motion_table(model, r), g.out + "_gait.mot");
  write_storage_atomic(reproduced_gait_residual_table(r), g.out + "_gait_residuals.sto");
  write_storage_atomic(reproduced_gait_contact_table(r), g.out + "_gait_contact_forces.sto");
  std::printf("%s\n", r.BriefReport().c_str());
  nlohmann::json metrics = reproduced_gait_metrics(model, r);
  if (g.gain_margin > 0) {
    const GainMarginSummary margin = gain_margin(model, driving, kin, contacts, o, {g.gain_margin});
    std::printf("%s\n", margin.BriefReport().c_str());
    metrics["gain_margin"] = margin.to_json();
  }
  write_text_atomic(g.out + "_gait.json", json_text(metrics, 2) + "\n");
  std::printf("wrote %s_gait.mot, _gait_residuals.sto, _gait_contact_forces.sto, _gait.json\n", g.out.c_str());
}

// gait's --tune* options: the controller's tuning before the walk.
void add_gait_tuning_options(CLI::App* gait, GaitArgs* g) {
  gait->add_option("--tune", g->tune,
                   "first tune the controller to walk without residuals: CMA-ES over the reflex gains, the CPG's amplitude and the "
                   "balance feedback's gains (trunk on the stance hip, swing-foot placement), this many simulations on every core; "
                   "writes PREFIX_cpg_tuned.json, which --cpg then replays")
      ->check(CLI::Range(0, 5000));
  gait->add_option("--tune-horizon", g->tuning.horizon_s,
                   "simulated time per tuning candidate, s (a tuned controller walks its horizon, not necessarily beyond: below --duration, a warning)")->check(CLI::Range(0.5, 30.0))->capture_default_str();
  gait->add_option("--tune-rounds", g->tuning.rounds, "CMA-ES restarts from the last best, horizons rising evenly to --tune-horizon")
      ->check(CLI::Range(1, 10))
      ->capture_default_str();
  gait->add_option("--tune-sigma", g->tuning.initial_step,
                   "CMA-ES' initial step size (1: a factor e in a gain, a trunk share of 1); smaller refines a tuned controller, e.g. 0.15")
      ->check(CLI::Range(0.01, 3.0))
      ->capture_default_str();
  gait->add_option("--tune-seed", g->tuning.seed, "CMA-ES' random seed (each round adds its index): another seed, another search")
      ->capture_default_str();
  gait->add_option("--tune-population", g->tuning.population,
                   "CMA-ES' population, candidates per generation: 0 (4 + 3 ln n, 10 for the 9 searched parameters) or at least 2, e.g. 20")
      ->check(CLI::Range(0, 200))
      ->capture_default_str();
  gait->add_option("--tune-restarts", g->tuning.restarts,
                   "when the tuned walk falls before the horizon, CMA-ES again from the best so far, up to this many times, each with "
                   "a round's share of --tune (on top of it), until a walk lasts the horizon")
      ->check(CLI::Range(0, 10))
      ->capture_default_str();
  gait->add_option("--tune-budget-simulated", g->tuning.restart_budget_s,
                   "simulated s: a restart begins only while the tuning's simulations so far plus the last round's again stay within "
                   "this (0: no bound)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  gait->add_option("--tune-step-decay", g->tuning.step_decay,
                   "each tuning round's and restart's initial step is the last's times this, e.g. 0.55: 0.5, 0.28, 0.15 over three rounds")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  gait->add_option("--tune-speeds", g->tuning.speeds, "speed knobs each tuning candidate walks at (its cost their mean), e.g. 0.8 1 1.2")
      ->check(CLI::Range(0.2, 5.0))
      ->capture_default_str();
  gait->add_option("--tune-steps", g->tuning.ground_steps_m,
                   "ground steps (m, negative: down) each tuning candidate also walks over, the edge under the pelvis at half the horizon (or --tune-step-at), "
                   "e.g. -0.02 0.01")
      ->check(CLI::Range(-0.2, 0.2));
  gait->add_option("--tune-pushes", g->tune_pushes_N_s,
                   "pushes each tuning candidate also walks through, impulses at the pelvis over 0.1 s at half the horizon, N s, "
                   "ground frame, three numbers each (x y z)");
  gait->add_option("--tune-step-at", g->tuning.ground_step_at,
                   "where each tuning ground step's edge reaches the pelvis, fractions of the horizon: each step is walked at each, "
                   "e.g. 0.45 0.5 0.55")
      ->check(CLI::Range(0.01, 0.99))
      ->capture_default_str();
  gait->add_option("--tune-stop-at", g->tuning.stop_at,
                   "walk -> stand trials each tuning candidate also walks, stopping at its stop phase after each of these fractions "
                   "of the horizon; only their falls count, e.g. 0.45")
      ->check(CLI::Range(0.01, 0.99));
  gait->add_option("--tune-tolerances", g->tuning.integrator_tolerances,
                   "integrator tolerances every tuning walk is taken at (each one more simulation), so the controller walks by its "
                   "own stability, not one tolerance's integration error, e.g. 5e-4 2e-3 (default: --tolerance alone; with "
                   "linearly_implicit_euler, walks in ros34pw2 at these tolerances besides its own)")
      ->check(CLI::Range(1e-8, 0.1));
  gait->add_flag("--tune-stance-hold", g->tuning.tune_stance_hold,
                 "tuning: also search the stance-foot hold's gains, the stance hip moving its foot across the way against the "
                 "pelvis' sideways offset and speed in single support");
  gait->add_flag("--tune-swing-world", g->tuning.tune_swing_world,
                 "tuning: also search the swing hip's world-frame share (SIMBICON's: the swing femur turned by the pelvis' orientation "
                 "error, so the foot lands headed as the trial's), from 1 where the CPG has no controller");
  gait->add_flag("--tune-ankle", g->tuning.tune_ankle,
                 "tuning: also search the lateral ankle strategy's gains, the stance foot rolled onto its outer edge as the pelvis "
                 "moves out over it in single support, from 1 rad/m and 0.3 rad s/m where the CPG has no controller");
  gait->add_flag("--tune-entrainment", g->tuning.tune_entrainment,
                 "tuning: also search the CPG's entrainment, the share of its phase error made up at each touchdown (see --entrainment)");
  gait->add_option("--tune-rotation-limit", g->tuning.worst_rotation_limit_deg,
                   "tuning: a walk whose worst rotation tracks the trial's cycle worse than this (deg RMS) costs as much as a fall")
      ->check(CLI::Range(0.0, 90.0));
  gait->add_option("--tune-cycle-weight", g->tuning.cycle_change_weight,
                   "tuning: cost per rad of a walk's cycle change, the RMS over its angles of its last cycle against the one before")
      ->check(CLI::Range(0.0, 1000.0));
  gait->add_option("--tune-drift-weight", g->tuning.drift_weight,
                   "tuning: cost per rad of a walk's drift, how far its cycle-mean walking direction and pelvis yaw moved from "
                   "its middle cycle to its last (walkers that drift within the horizon fall soon after it)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
}

// gait's trials of a walk: walk -> stand, a push, a ground step, and the gain margin.
void add_gait_trial_options(CLI::App* gait, GaitArgs* g) {
  gait->add_option("--stop-at", g->options.stop_time_s,
                   "walk -> stand: from this time, s, stop the walk at the next --stop-phase: the CPG fades out, the reflexes turn to a "
                   "standing pose (feet flat, the centre of mass over them) and an ankle and hip balance holds it");
  gait->add_option("--stop-over", g->options.stop_over_s, "walk -> stand: the treadmill belt's time to halt once the walk froze, s (default 0.3)");
  gait->add_option("--stop-phase", g->options.stop_phase, "walk -> stand: the cycle phase (0-1 from the CPG foot's heel strike) where the walk stops (0.3: that foot's mid-stance)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  gait->add_option("--stand-blend", g->options.stand_blend_s, "walk -> stand: the reflexes' time to turn from the stopped pose to the standing one, s")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  gait->add_option("--stand-fade", g->options.stand_fade_s, "walk -> stand: the CPG's excitations' time to fade out, s")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  gait->add_option("--stand-reflex-gain", g->options.stand_reflex_gain,
                   "walk -> stand: the joint reflex's gains standing, times the walk's (reached over --stand-blend): the reflexes alone hold the pose")
      ->check(CLI::Range(0.1, 10.0))
      ->capture_default_str();
  gait->add_option("--push-time", g->options.push_time_s, "push the pelvis at this time, s (with --push-force)");
  gait->add_option("--push-force", g->push_force_N, "the push's force at the pelvis' origin, N, ground frame (x y z)")->expected(3);
  gait->add_option("--push-duration", g->options.push_duration_s, "how long the push lasts, s (impulse: force x duration)")
      ->check(CLI::Range(0.001, 5.0))
      ->capture_default_str();
  gait->add_option("--step-height", g->options.ground_step_m, "a step in the ground, m (negative: down), its edge along ground x")
      ->check(CLI::Range(-0.2, 0.2));
  gait->add_option("--step-time", g->options.ground_step_time_s,
                   "when the step's edge reaches where the pelvis started (carried by a treadmill's belt), s")
      ->capture_default_str();
  gait->add_option("--gain-margin", g->gain_margin,
                   "after the walk, walk again with each feedback gain (reflex, trunk, foot placement) scaled in turn by F and by 1/F, "
                   "the others as they are: how many still walk (_gait.json's gain_margin), e.g. 0.8 (0: none)")
      ->check(CLI::Range(0.0, 0.999))
      ->capture_default_str();
}

// gait: the reproduced gait, driven by a fitted CPG.
void add_gait_command(CLI::App& app) {
  auto* gait = app.add_subcommand(
      "gait",
      "Reproduced gait: the muscle-driven model on contact spheres (no GRF) fitted to the trial's feet, excited\n"
      "by a fitted CPG with its feedback and a joint-angle reflex, the pelvis' rotations held on the trial's\n"
      "kinematics by residual actuators and its translations by soft springs (reported; --no-residuals to walk\n"
      "without). Outputs: PREFIX_gait.mot (deg, m), _gait_residuals.sto\n"
      "(N m, N), _gait_contact_forces.sto (N, ground frame), _gait.json (heel strikes, stride time and length,\n"
      "speed, tracking RMS per coordinate against the trial (deg or m), residuals as % body weight, falls).");
  auto g = std::make_shared<GaitArgs>();
  gait->add_option("--model", g->model, "OpenSim model (.osim) with muscles")->required()->check(CLI::ExistingFile);
  gait->add_option("--scale-muscles-from", g->generic_model,
                   "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  gait->add_option("--cpg", g->cpg, "fitted CPG (cpgait cpg fit, or the pipeline's _cpg.json)")->required()->check(CLI::ExistingFile);
  gait->add_option("--kinematics", g->kinematics, "the trial's coordinates (IK .mot): initial state, reference")->required()->check(CLI::ExistingFile);
  gait->add_option("--start", g->start, "a heel strike of the CPG's foot in the trial, s (default: the first, Zeni's method)");
  gait->add_option("--begin", g->options.begin_time_s,
                   "where the simulation begins in the trial, s (default: at the heel strike, at the CPG's start phase)");
  gait->add_option("--duration", g->options.duration_s, "simulated time, s")->check(CLI::Range(0.01, 60.0))->capture_default_str();
  gait->add_option("--speed", g->options.speed, "CPG speed knob (the reference is time-scaled alike)")->check(CLI::Range(0.2, 5.0))->capture_default_str();
  gait->add_option("--amplitude", g->options.amplitude, "CPG amplitude knob")->check(CLI::Range(0.0, 5.0))->capture_default_str();
  gait->add_flag("--no-residuals", g->no_residuals, "no pelvis residual actuators: walk until the model falls");
  add_gait_tuning_options(gait, g.get());
  add_gait_trial_options(gait, g.get());
  gait->add_option("--entrainment", g->entrainment,
                   "the CPG's entrainment by phase resetting: at each touchdown this share (0-1) of its phase error against the "
                   "foot's heel-strike phase is made up over about 0.1 s (default: the controller's, else 0: open loop)")
      ->check(CLI::Range(0.0, 1.0));
  gait->add_option("--entrainment-phases", g->entrainment_phases,
                   "the heel-strike phases (0-1 of the CPG's cycle) --entrainment resets the right and the left foot's touchdowns to "
                   "(default: the controller's, else 0 0.5)")
      ->expected(2);
  gait->add_option("--reflex-kp", g->options.reflex_kp, "joint-angle reflex gain, excitation per (m x rad)")->capture_default_str();
  gait->add_option("--reflex-kv", g->options.reflex_kv, "joint-speed reflex gain, excitation per (m x rad/s)")->capture_default_str();
  g->tolerance_option = gait->add_option("--tolerance", g->options.integrator_tolerance,
                                         "integrator error tolerance (relative and absolute); default: the one the CPG's controller was "
                                         "tuned at, else this")
                            ->check(CLI::Range(1e-8, 1e-1))
                            ->capture_default_str();
  g->control_interval_option =
      gait->add_option("--control-interval", g->options.control_interval_s,
                       "the controller's interval, s: the CPG, reflexes and balance feedback are updated once per interval (also the "
                       "integrator's largest step and the output's sample); default: the one the CPG's controller was tuned at, else this")
          ->check(CLI::Range(1e-4, 1e-2))
          ->capture_default_str();
  g->integrator_option =
      gait->add_option("--integrator", g->options.integrator,
                       "ros34pw2 (third-order Rosenbrock-W), rosenbrock (ROS2: the walks before ros34pw2, with --control-interval 0.001) or "
                       "linearly_implicit_euler (first order, one step per interval; --tolerance unused); default: the controller's, else ros34pw2")
          ->transform(CLI::CheckedTransformer(w_methods_by_name()));
  gait->add_flag("--compliant-tendons", g->options.compliant_tendons,
                 "compliant tendons (OpenSim's Thelen2003Muscle; suits a CPG fitted to CMC excitations). Default: rigid, as static "
                 "optimization assumes");
  gait->add_option("--passive-stiffness", g->options.passive_stiffness_Nm_per_rad,
                   "stiffness of the passive joints (coordinates named mtp_*), N m/rad; 0: none")
      ->capture_default_str();
  gait->add_option("--passive-damping", g->options.passive_damping_Nms_per_rad, "damping of the passive joints, N m s/rad")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  gait->add_flag("--no-foot-fit", g->no_foot_fit,
                 "default spheres as placed on the model; without it each sphere's radius is fitted so the trial's poses load the "
                 "feet with body weight on average");
  gait->add_option("--contacts", g->contacts,
                   "contact spheres JSON (cpgait.contact/1); default: --foot-spheres. A file without ground_height_m or "
                   "ground_velocity_m_s gets the default feet's ground (under the recorded feet) and fitting")
      ->check(CLI::ExistingFile);
  gait->add_option("--foot-spheres", g->foot_spheres,
                   "contact spheres per foot without --contacts: 2 (heel, toes) or 5 (medial and lateral heel, first and fifth "
                   "metatarsal heads, toes); default: those the CPG's controller was tuned on, else 2")
      ->check(CLI::IsMember({2, 5}));
  gait->add_option("-o,--output", g->out, "output prefix")->required();
  gait->callback([g] { run_gait(*g); });
}

}  // namespace

void add_cpg_commands(CLI::App& app) {
  auto* cpg = app.add_subcommand("cpg", "Central pattern generators (Matsuoka neurons): fit one to a trial's muscle patterns, run one.");
  cpg->require_subcommand(1);
  add_cpg_fit_command(*cpg);
  add_cpg_run_command(*cpg);
  add_gait_command(app);
}

}  // namespace cpgait::services
