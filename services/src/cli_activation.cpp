// so and cmc: static optimization and computed muscle control from the command line and from
// OpenSim AnalyzeTool and CMCTool setups.
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/activation/static_optimization.h"
#include "cpgait/capture/cmc_setup.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/dynamics/forward_simulation.h"
#include "cpgait/capture/analyze_setup.h"
#include "cpgait/capture/input_error.h"
#include "cpgait/model/osim_reader.h"
#include "output_files.h"
#include "setup_files.h"

namespace cpgait::services {
namespace fs = std::filesystem;

namespace {

struct SoInputs {
  std::string model, generic_model, coordinates, loads, grf, out_dir, name = "static_optimization";
  std::vector<std::string> actuator_files;
  bool use_model_actuators = true;
  bool replace_force_set = false;
  StaticOptimizationOptions options;
};

// What so, cmc and forward all read: the model (muscles dropped when the actuator files replace its
// force set, as OpenSim does; muscle lengths scaled from the generic model when one is given), its
// actuators plus those of the files, the external loads, and - when asked for and there are no
// loads - contact spheres (the file's, else two per foot).
struct DynamicsInputs {
  OsimReadResult model;
  std::vector<ActuatorSpec> actuators;
  std::unique_ptr<AppliedLoads> loads;
  std::optional<ContactSet> contacts;
};
DynamicsInputs read_dynamics_inputs(const std::string& model, const std::string& generic_model, const std::vector<std::string>& actuator_files,
                                    bool use_model_actuators, bool replace_force_set, const std::string& loads,
                                    const std::string& grf, bool contacts_without_loads = false,
                                    const std::string& contacts_file = "") {
  DynamicsInputs d;
  d.model = read_muscle_model(model, generic_model);
  if (replace_force_set) d.model.model.muscles.clear();
  else if (use_model_actuators) d.actuators = read_actuators(model);
  // As OpenSim's ForceSet::append: an actuator whose name the set already has is not added again.
  for (const auto& f : actuator_files)
    for (auto& a : read_actuators(f)) {
      const bool known = std::any_of(d.actuators.begin(), d.actuators.end(), [&](const auto& b) { return b.name == a.name; });
      if (known) d.model.warnings.push_back(f + ": actuator '" + a.name + "' is already in the model's force set; the model's is used, as OpenSim does");
      else d.actuators.push_back(std::move(a));
    }
  if (!loads.empty()) {
    const ExternalLoadsSpec spec = read_external_loads(loads);
    const std::string data = !grf.empty() ? grf : resolve_setup_file(spec.setup_dir, spec.datafile, loads, "datafile");
    d.loads = std::make_unique<AppliedLoads>(d.model.model, spec, read_storage(data));
  }
  if (!d.loads && contacts_without_loads) {
    d.contacts = contacts_file.empty() ? default_foot_contacts(d.model.model) : read_contact_set(contacts_file, d.model.model);
    if (d.contacts->spheres.empty())
      throw InputError(model, 0, "contacts", "no GRF was given and the model has no calcn_/toes_ or foot_ bodies for default contact spheres: give --loads or --contacts");
  }
  return d;
}

void run_so(const SoInputs& in) {
  DynamicsInputs d = read_dynamics_inputs(in.model, in.generic_model, in.actuator_files, in.use_model_actuators, in.replace_force_set, in.loads, in.grf);
  OsimReadResult& mr = d.model;
  const ResolvedActuators actuators(mr.model, d.actuators);
  const std::unique_ptr<AppliedLoads>& loads = d.loads;
  const StaticOptimizationResult r =
      static_optimization(mr.model, read_storage(in.coordinates), loads.get(), actuators, in.options);
  print_warnings(r.summary.warnings);
  ensure_directory(in.out_dir);
  const std::string a = (fs::path(in.out_dir) / (in.name + "_StaticOptimization_activation.sto")).string();
  const std::string f = (fs::path(in.out_dir) / (in.name + "_StaticOptimization_force.sto")).string();
  write_storage_atomic(static_optimization_activation_table(r), a);
  write_storage_atomic(static_optimization_force_table(r), f);
  std::printf("%s%s\nwrote %s\nwrote %s\n", r.summary.BriefReport().c_str(), loads ? " with external loads" : "", a.c_str(),
              f.c_str());
}


struct CmcInputs {
  std::string model, generic_model, kinematics, tasks, constraints, loads, grf, contacts, out_dir, name = "cmc";
  std::vector<std::string> actuator_files;
  bool replace_force_set = false;
  bool no_contact = false;
  ComputedMuscleControlOptions options;
};

void run_cmc(const CmcInputs& in) {
  DynamicsInputs d = read_dynamics_inputs(in.model, in.generic_model, in.actuator_files, true, in.replace_force_set, in.loads, in.grf, !in.no_contact, in.contacts);
  OsimReadResult& mr = d.model;
  const ResolvedActuators actuators(mr.model, d.actuators);
  const std::unique_ptr<AppliedLoads>& loads = d.loads;
  const std::optional<ContactSet>& contacts = d.contacts;
  const std::vector<CmcJointTask> tasks = read_cmc_tasks(in.tasks);
  std::optional<ControlSetSpec> constraints;
  if (!in.constraints.empty()) constraints = read_control_set(in.constraints);
  const ComputedMuscleControlResult r =
      computed_muscle_control(mr.model, read_storage(in.kinematics), loads.get(), contacts ? &*contacts : nullptr, actuators,
                              tasks, constraints ? &*constraints : nullptr, in.options);
  print_warnings(r.summary.warnings);
  ensure_directory(in.out_dir);
  auto path = [&](const char* suffix) { return (fs::path(in.out_dir) / (in.name + suffix)).string(); };
  write_storage_atomic(cmc_controls_table(r), path("_controls.sto"));
  write_storage_atomic(cmc_states_table(r), path("_states.sto"));
  write_storage_atomic(cmc_kinematics_q_table(mr.model, r), path("_Kinematics_q.sto"));
  write_storage_atomic(cmc_position_error_table(r), path("_pErr.sto"));
  write_storage_atomic(cmc_actuation_force_table(r), path("_Actuation_force.sto"));
  write_text_atomic(path("_avgResiduals.txt"), cmc_average_residuals_text(r));
  std::printf("%s\n", r.summary.BriefReport().c_str());
  const Eigen::VectorXd rms = r.position_error_rms();
  int worst = 0;
  for (int c = 0; c < rms.size(); ++c)
    if (mr.model.coordinates[c].is_angle() && rms[c] > rms[worst]) worst = c;
  std::printf("tracking error (RMS): worst rotational %s %.3f deg\n", r.coordinate_names[worst].c_str(), rms[worst] * 180 / M_PI);
  std::printf("%s", cmc_average_residuals_text(r).c_str());
  std::printf("wrote %s_{controls,states,Kinematics_q,pErr,Actuation_force}.sto and %s_avgResiduals.txt in %s\n",
              in.name.c_str(), in.name.c_str(), in.out_dir.c_str());
}


struct ForwardInputs {
  std::string model, generic_model, controls, states, loads, grf, contacts, desired, out_dir, name = "forward";
  std::vector<std::string> actuator_files;
  bool replace_force_set = false;
  bool no_contact = false;
  ForwardSimulationOptions options;
};

void run_forward(const ForwardInputs& in) {
  DynamicsInputs d = read_dynamics_inputs(in.model, in.generic_model, in.actuator_files, true, in.replace_force_set, in.loads, in.grf, !in.no_contact, in.contacts);
  OsimReadResult& mr = d.model;
  const ResolvedActuators actuators(mr.model, d.actuators);
  const std::unique_ptr<AppliedLoads>& loads = d.loads;
  const std::optional<ContactSet>& contacts = d.contacts;
  std::vector<std::string> missing, warnings;
  const bool xml = in.controls.size() > 4 && in.controls.compare(in.controls.size() - 4, 4, ".xml") == 0;
  const ControlHistory controls =
      xml ? control_history_from_control_set(mr.model, actuators, read_control_set(in.controls), in.controls, &missing)
          : control_history_from_table(mr.model, actuators, read_storage(in.controls), &missing);
  if (!missing.empty())
    warnings.push_back(std::to_string(missing.size()) + " controls are not in " + in.controls + " (muscles at their minimum, actuators off), e.g. " + missing.front());
  const Storage states = read_storage(in.states);
  const Eigen::VectorXd x0 = initial_state_from_table(mr.model, states, in.options.t0_s, in.options.compliant_tendons, &warnings);
  std::optional<Storage> desired;
  if (in.options.correction_kp || in.options.correction_kv) desired = read_storage(in.desired.empty() ? in.states : in.desired);
  const ForwardSimulationResult r = forward_simulation(mr.model, actuators, loads.get(), contacts ? &*contacts : nullptr, controls, x0,
                                                       in.options, desired ? &*desired : nullptr);
  warnings.insert(warnings.end(), r.warnings.begin(), r.warnings.end());
  print_warnings(warnings);
  ensure_directory(in.out_dir);
  auto path = [&](const char* suffix) { return (fs::path(in.out_dir) / (in.name + suffix)).string(); };
  write_storage_atomic(forward_states_table(r), path("_states.sto"));
  write_storage_atomic(forward_kinematics_q_table(mr.model, r), path("_Kinematics_q.sto"));
  write_storage_atomic(forward_actuation_force_table(r), path("_Actuation_force.sto"));
  if (!r.contact_names.empty()) write_storage_atomic(forward_contact_force_table(r), path("_contact_forces.sto"));
  std::printf("%s\nwrote %s_{states,Kinematics_q,Actuation_force%s}.sto in %s\n", r.BriefReport().c_str(), in.name.c_str(),
              r.contact_names.empty() ? "" : ",contact_forces", in.out_dir.c_str());
}

}  // namespace

void run_so_setup(const std::string& setup_path, const ToolOverrides& o) {
  const AnalyzeSetup s = read_analyze_setup(setup_path);
  if (!s.has_static_optimization)
    throw InputError(setup_path, 0, "AnalysisSet", "the AnalyzeTool setup has no StaticOptimization analysis that is on");
  SoInputs in;
  in.model = o.model_file(s.setup_dir, s.model_file, setup_path);
  in.generic_model = o.generic_model;
  in.coordinates = resolve_setup_file(s.setup_dir, s.coordinates_file, setup_path, "coordinates_file");
  if (in.coordinates.empty())
    throw InputError(setup_path, 0, "coordinates_file", "static optimization needs a coordinates_file (cpgait reads a states file for MuscleAnalysis only)");
  in.loads = resolve_setup_file(s.setup_dir, s.external_loads_file, setup_path, "external_loads_file");
  for (const auto& f : s.force_set_files) in.actuator_files.push_back(resolve_setup_file(s.setup_dir, f, setup_path, "force_set_files"));
  in.use_model_actuators = s.use_model_force_set;
  in.replace_force_set = s.replace_force_set;
  in.options.activation_exponent = s.activation_exponent;
  in.options.use_muscle_physiology = s.use_muscle_physiology;
  in.options.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  in.options.time_range_s = s.time_range_s;
  in.options.step_interval = s.step_interval;
  in.out_dir = o.results_dir(s.setup_dir, s.results_directory);
  in.name = s.name.empty() ? "static_optimization" : s.name;
  run_so(in);
}

void run_cmc_setup(const std::string& setup_path, const ToolOverrides& o) {
  const CmcSetup s = read_cmc_setup(setup_path);
  CmcInputs in;
  in.model = o.model_file(s.setup_dir, s.model_file, setup_path);
  in.generic_model = o.generic_model;
  in.kinematics = resolve_setup_file(s.setup_dir, s.desired_kinematics_file, setup_path, "desired_kinematics_file");
  in.tasks = resolve_setup_file(s.setup_dir, s.task_set_file, setup_path, "task_set_file");
  in.constraints = resolve_setup_file(s.setup_dir, s.constraints_file, setup_path, "constraints_file");
  in.loads = resolve_setup_file(s.setup_dir, s.external_loads_file, setup_path, "external_loads_file");
  for (const auto& f : s.force_set_files) in.actuator_files.push_back(resolve_setup_file(s.setup_dir, f, setup_path, "force_set_files"));
  in.replace_force_set = s.replace_force_set;
  in.options.time_range_s = std::make_pair(s.initial_time_s, s.final_time_s);
  in.options.window_s = s.cmc_time_window_s;
  in.options.lowpass_cutoff_hz = s.lowpass_cutoff_hz;
  // OpenSim applies no ground forces when the setup gives no external loads (a swinging leg, a
  // hanging block); cpgait's contact spheres are for `cpgait cmc` without --loads.
  in.no_contact = in.loads.empty();
  // The setup's integrator_error_tolerance is OpenSim's integrator's (another method and norm); the
  // default of ComputedMuscleControlOptions is used instead.
  if (!s.use_fast_target) std::fprintf(stderr, "warning: the slow optimization target is not implemented; using the fast target\n");
  in.out_dir = o.results_dir(s.setup_dir, s.results_directory);
  in.name = s.name.empty() ? "cmc" : s.name;
  run_cmc(in);
}

void run_forward_setup(const std::string& setup_path, const ToolOverrides& o) {
  const ForwardSetup s = read_forward_setup(setup_path);
  ForwardInputs in;
  in.model = o.model_file(s.setup_dir, s.model_file, setup_path);
  in.generic_model = o.generic_model;
  in.controls = resolve_setup_file(s.setup_dir, s.controls_file, setup_path, "controls_file");
  if (s.states_file.empty()) throw InputError(setup_path, 0, "states_file", "the Forward setup names no states_file (the initial state)");
  in.states = resolve_setup_file(s.setup_dir, s.states_file, setup_path, "states_file");
  in.loads = resolve_setup_file(s.setup_dir, s.external_loads_file, setup_path, "external_loads_file");
  for (const auto& f : s.force_set_files) in.actuator_files.push_back(resolve_setup_file(s.setup_dir, f, setup_path, "force_set_files"));
  in.replace_force_set = s.replace_force_set;
  in.options.t0_s = s.initial_time_s;
  in.options.t1_s = s.final_time_s;
  in.options.correction_kp = s.correction_kp;
  in.options.correction_kv = s.correction_kv;
  in.out_dir = o.results_dir(s.setup_dir, s.results_directory);
  in.name = s.name.empty() ? "forward" : s.name;
  run_forward(in);
}

namespace {

// so
void add_so_command(CLI::App& app) {
  auto* so = app.add_subcommand(
      "so",
      "Static optimization: muscle activations and actuator controls that reproduce the inverse-dynamics\n"
      "generalized forces at each frame, minimising sum of control^p. Inputs: .osim model (muscles),\n"
      "coordinates .mot/.sto (degrees unless inDegrees=no), optional ExternalLoads .xml with its GRF .mot,\n"
      "actuator ForceSet .xml files (residuals, reserves). Outputs in DIR: <name>_StaticOptimization_activation.sto\n"
      "(activations 0-1 and actuator controls) and <name>_StaticOptimization_force.sto (N, or N m for torques).");
  auto a = std::make_shared<SoInputs>();
  auto time = std::make_shared<std::vector<double>>();
  auto no_physiology = std::make_shared<bool>(false);
  so->add_option("--model", a->model, "OpenSim model (.osim)")->required()->check(CLI::ExistingFile);
  so->add_option("--scale-muscles-from", a->generic_model,
                 "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  so->add_option("--coordinates", a->coordinates, "coordinates (.mot/.sto), e.g. the IK result")->required()->check(CLI::ExistingFile);
  so->add_option("--loads", a->loads, "ExternalLoads .xml")->check(CLI::ExistingFile);
  so->add_option("--grf", a->grf, "GRF data .mot (default: the datafile the loads name)")->check(CLI::ExistingFile);
  so->add_option("--actuators", a->actuator_files, "actuator ForceSet .xml files (repeatable)")->check(CLI::ExistingFile);
  so->add_option("--cutoff", a->options.lowpass_cutoff_hz, "low-pass cutoff for the coordinates, Hz (negative: none)")
      ->capture_default_str();
  so->add_option("--time", *time, "first and last time, seconds")->expected(2);
  so->add_option("--exponent", a->options.activation_exponent, "activation exponent p (>= 2)")
      ->check(CLI::Range(2.0, 100.0))
      ->capture_default_str();
  so->add_option("--step", a->options.step_interval, "analyse every n-th sample")->capture_default_str();
  so->add_flag("--no-physiology", *no_physiology, "use max isometric force instead of force-length-velocity");
  so->add_option("--name", a->name, "output file prefix")->capture_default_str();
  so->add_option("-o,--output", a->out_dir, "output folder")->required();
  so->callback([a, time, no_physiology] {
    if (time->size() == 2) a->options.time_range_s = std::make_pair((*time)[0], (*time)[1]);
    a->options.use_muscle_physiology = !*no_physiology;
    run_so(*a);
  });
}

// cmc
void add_cmc_command(CLI::App& app) {
  auto* cmc = app.add_subcommand(
      "cmc",
      "Computed muscle control (OpenSim's CMC, fast target): muscle excitations that make the muscle-driven\n"
      "model track desired kinematics, window by window (PD task accelerations -> force distribution ->\n"
      "excitations -> forward dynamics). With --loads the measured GRF act on the model; without, contact\n"
      "spheres do (--contacts JSON, default two per foot). Outputs in DIR: <name>_controls.sto, _states.sto,\n"
      "_Kinematics_q.sto (deg), _pErr.sto (rad, m), _Actuation_force.sto, _avgResiduals.txt.");
  auto c = std::make_shared<CmcInputs>();
  auto ctime = std::make_shared<std::vector<double>>();
  cmc->add_option("--model", c->model, "OpenSim model (.osim)")->required()->check(CLI::ExistingFile);
  cmc->add_option("--scale-muscles-from", c->generic_model,
                 "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  cmc->add_option("--kinematics", c->kinematics, "desired coordinates (.mot/.sto), e.g. RRA's or IK's")->required()->check(CLI::ExistingFile);
  cmc->add_option("--tasks", c->tasks, "CMC task set .xml (coordinates tracked, kp, kv)")->required()->check(CLI::ExistingFile);
  cmc->add_option("--constraints", c->constraints, "control constraints ControlSet .xml")->check(CLI::ExistingFile);
  cmc->add_option("--actuators", c->actuator_files, "actuator ForceSet .xml files (residuals, reserves; repeatable)")->check(CLI::ExistingFile);
  cmc->add_option("--loads", c->loads, "ExternalLoads .xml (measured GRF)")->check(CLI::ExistingFile);
  cmc->add_option("--grf", c->grf, "GRF data .mot (default: the datafile the loads name)")->check(CLI::ExistingFile);
  cmc->add_option("--contacts", c->contacts, "contact spheres JSON (cpgait.contact/1) used without --loads")->check(CLI::ExistingFile);
  cmc->add_option("--integrator", c->options.integrator,
                  "ros34pw2 (third-order Rosenbrock-W, stiff muscles implicit; the default), rosenbrock (ROS2, second order) or dopri (explicit 5(4))")
      ->transform(CLI::CheckedTransformer(std::map<std::string, CmcIntegrator>{{"ros34pw2", CmcIntegrator::kRos34pw2},
                                                                                {"rosenbrock", CmcIntegrator::kRosenbrockW},
                                                                                {"dopri", CmcIntegrator::kDormandPrince}}));
  cmc->add_flag("--refresh-actuators", c->options.refresh_actuators,
                "also re-solve residual and reserve actuators every output interval (default: once per window, as OpenSim)");
  cmc->add_flag("!--rigid-tendons", c->options.compliant_tendons, "rigid tendons (default: compliant, as OpenSim's Thelen2003Muscle)");
  cmc->add_flag("--no-contact", c->no_contact, "without --loads, apply no ground forces at all (residuals carry the body)");
  cmc->add_option("--time", *ctime, "first and last time, seconds")->expected(2);
  cmc->add_option("--window", c->options.window_s, "CMC time window, s")->check(CLI::Range(1e-3, 0.5))->capture_default_str();
  cmc->add_option("--cutoff", c->options.lowpass_cutoff_hz, "low-pass cutoff for the desired kinematics, Hz (negative: none)")->capture_default_str();
  cmc->add_option("--tolerance", c->options.integrator_tolerance, "integrator error tolerance (default: 2e-4 for ros34pw2, 1e-3 for the others)")
      ->check(CLI::Range(1e-10, 1e-2));
  cmc->add_option("--name", c->name, "output file prefix")->capture_default_str();
  cmc->add_option("-o,--output", c->out_dir, "output folder")->required();
  cmc->callback([c, ctime] {
    if (ctime->size() == 2) c->options.time_range_s = std::make_pair((*ctime)[0], (*ctime)[1]);
    run_cmc(*c);
  });
}

// forward
void add_forward_command(CLI::App& app) {
  auto* fwd = app.add_subcommand(
      "forward",
      "Forward simulation (OpenSim's Forward tool): the muscle-driven model from an initial state under given\n"
      "controls, e.g. CMC's. Controls: CMC's _controls.sto or an OpenSim ControlSet .xml; initial state: the\n"
      "row of a states .sto at or before the start time. With --loads the measured GRF act; without, contact\n"
      "spheres. Outputs in DIR: <name>_states.sto, _Kinematics_q.sto (deg), _Actuation_force.sto, and\n"
      "_contact_forces.sto (N, ground frame) with spheres.");
  auto fw = std::make_shared<ForwardInputs>();
  auto ftime = std::make_shared<std::vector<double>>();
  auto kp = std::make_shared<double>(-1), kv = std::make_shared<double>(-1);
  fwd->add_option("--model", fw->model, "OpenSim model (.osim)")->required()->check(CLI::ExistingFile);
  fwd->add_option("--scale-muscles-from", fw->generic_model,
                 "generic .osim the model was scaled from: muscle fibre and tendon lengths scaled as OpenSim's ScaleTool does")
      ->check(CLI::ExistingFile);
  fwd->add_option("--controls", fw->controls, "controls: CMC's _controls.sto or a ControlSet .xml")->required()->check(CLI::ExistingFile);
  fwd->add_option("--states", fw->states, "states .sto holding the initial state")->required()->check(CLI::ExistingFile);
  fwd->add_option("--actuators", fw->actuator_files, "actuator ForceSet .xml files (repeatable)")->check(CLI::ExistingFile);
  fwd->add_option("--loads", fw->loads, "ExternalLoads .xml (measured GRF)")->check(CLI::ExistingFile);
  fwd->add_option("--grf", fw->grf, "GRF data .mot (default: the datafile the loads name)")->check(CLI::ExistingFile);
  fwd->add_option("--contacts", fw->contacts, "contact spheres JSON (cpgait.contact/1) used without --loads")->check(CLI::ExistingFile);
  fwd->add_flag("--no-contact", fw->no_contact, "without --loads, no ground forces at all");
  fwd->add_option("--time", *ftime, "first and last time, seconds")->expected(2)->required();
  fwd->add_option("--correction-kp", *kp, "CorrectionController kp, N m per rad (toward the states' or --desired coordinates)");
  fwd->add_option("--correction-kv", *kv, "CorrectionController kv, N m s per rad");
  fwd->add_option("--desired", fw->desired, "coordinates the correction controller tracks (default: the states file)")->check(CLI::ExistingFile);
  fwd->add_flag("!--rigid-tendons", fw->options.compliant_tendons, "rigid tendons (default: compliant)");
  fwd->add_option("--name", fw->name, "output file prefix")->capture_default_str();
  fwd->add_option("-o,--output", fw->out_dir, "output folder")->required();
  fwd->callback([fw, ftime, kp, kv] {
    fw->options.t0_s = (*ftime)[0];
    fw->options.t1_s = (*ftime)[1];
    if (!(fw->options.t1_s > fw->options.t0_s)) throw CLI::ValidationError("--time", "the last time must be after the first");
    if (*kp >= 0) fw->options.correction_kp = *kp;
    if (*kv >= 0) fw->options.correction_kv = *kv;
    run_forward(*fw);
  });
}

}  // namespace

void add_activation_commands(CLI::App& app) {
  add_so_command(app);
  add_cmc_command(app);
  add_forward_command(app);
}

}  // namespace cpgait::services
