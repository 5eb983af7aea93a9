// Forward dynamics on one thread: evaluations of qdd = M^-1 (tau - bias) per second on gait2392.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "cpgait/activation/computed_muscle_control.h"
#include "cpgait/capture/ik_setup.h"
#include "cpgait/capture/text_lines.h"
#include "cpgait/capture/trc.h"
#include "cpgait/dynamics/forward_dynamics.h"
#include "cpgait/dynamics/muscle_driven_dynamics.h"
#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/muscles/scale_muscle_parameters.h"
#include "cpgait/gait/reproduced_gait.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/kinematics/gait_events.h"
#include "cpgait/model/osim_reader.h"
#include "pipeline.h"

using namespace cpgait;

static void BM_ForwardDynamicsGait2392(benchmark::State& state) {
  const std::string model = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/OutputReference/subject01_simbody.osim";
  if (!std::filesystem::exists(model)) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model m = read_osim(model).model;
  const int n = m.num_coordinates();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  Eigen::VectorXd q = m.default_coordinates(), qd(n), tau(n), qdd(n);
  for (int i = 0; i < n; ++i) q[i] += u(rng), qd[i] = 2 * u(rng), tau[i] = 20 * u(rng);
  ForwardDynamicsWorkspace ws(m);
  const std::vector<Vector6d> none;
  for (auto _ : state) {
    forward_dynamics(m, q.data(), qd.data(), tau.data(), none, ws, qdd.data());
    benchmark::DoNotOptimize(qdd.data());
  }
  state.counters["evaluations/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ForwardDynamicsGait2392)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The muscle-driven model (92 compliant Thelen muscles, CMC's actuators, GRF): state derivatives per
// second, the integrators' unit of work.
static void BM_MuscleDrivenDerivativesGait2392(benchmark::State& state) {
  const std::string pl = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(pl + "gait2392_CMC_Actuators.xml")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model m = read_osim(pl + "OutputReference/subject01_simbody_adjusted.osim").model;
  const ResolvedActuators acts(m, read_actuators(pl + "gait2392_CMC_Actuators.xml"));
  const AppliedLoads loads(m, read_external_loads(pl + "subject01_walk1_grf.xml"), read_storage(pl + "subject01_walk1_grf.mot"));
  MuscleDrivenSystem sys;
  sys.model = &m;
  sys.actuators = &acts;
  sys.loads = &loads;
  MuscleDrivenWorkspace ws(sys);
  const int nq = m.num_coordinates(), nm = sys.num_muscles();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(sys.state_size()), dx(sys.state_size());
  x.head(nq) = m.default_coordinates();
  for (int k = 0; k < nm; ++k) {
    x[sys.activation_index(k)] = 0.2;
    x[sys.fiber_length_index(k)] = m.muscles[k].optimal_fiber_length_m;
  }
  const Eigen::VectorXd u = Eigen::VectorXd::Constant(nm, 0.3), c = Eigen::VectorXd::Zero(acts.size());
  for (auto _ : state) {
    muscle_driven_derivatives(sys, 1.0, x, u, c, ws, dx);
    benchmark::DoNotOptimize(dx.data());
  }
  state.counters["evaluations/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MuscleDrivenDerivativesGait2392)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// CMC on OpenSim's subject01 setup (0.5-2.0 s, measured loads), one thread: simulated seconds per
// wall-clock second (the issue's target: faster than real time).
static void BM_CmcSubject01(benchmark::State& state) {
  const std::string pl = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(pl + "gait2392_CMC_Tasks.xml")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model m = read_osim(pl + "OutputReference/subject01_simbody_adjusted.osim").model;
  const ResolvedActuators acts(m, read_actuators(pl + "gait2392_CMC_Actuators.xml"));
  const AppliedLoads loads(m, read_external_loads(pl + "subject01_walk1_grf.xml"), read_storage(pl + "subject01_walk1_grf.mot"));
  const auto tasks = read_cmc_tasks(pl + "gait2392_CMC_Tasks.xml");
  const auto constraints = read_control_set(pl + "gait2392_CMC_ControlConstraints.xml");
  const Storage kin = read_storage(pl + "OutputReference/ResultsRRA/subject01_walk1_RRA_Kinematics_q.sto");
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(0.5, 2.0);
  double simulated = 0;
  for (auto _ : state) {
    const auto r = computed_muscle_control(m, kin, &loads, nullptr, acts, tasks, &constraints, o);
    simulated += r.summary.simulated_s;
  }
  state.counters["simulated_s_per_s"] = benchmark::Counter(simulated, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CmcSubject01)->Unit(benchmark::kSecond)->Iterations(2);

// CMC on gait10dof18musc's shipped setup (18 Millard2012EquilibriumMuscles with elastic tendons,
// reserves appended to the model's actuators, 5 ms windows, 0.6-1.9 s), one thread: simulated
// seconds per wall-clock second (OpenSim 4.1 here: 0.0075).
static void BM_CmcGait10dof18muscMillard(benchmark::State& state) {
  const std::string g = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait10dof18musc/OutputReference/";
  if (!std::filesystem::exists(g + "gait10dof_Kinematics_Tracking_Tasks.xml")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait10dof18musc");
    return;
  }
  const Model m = read_osim(g + "subject01.osim").model;
  std::vector<ActuatorSpec> specs = read_actuators(g + "subject01.osim");
  for (auto& a : read_actuators(g + "gait10dof_Reserve_Actuators.xml"))
    if (std::none_of(specs.begin(), specs.end(), [&](const ActuatorSpec& b) { return b.name == a.name; })) specs.push_back(a);
  const ResolvedActuators acts(m, specs);
  const AppliedLoads loads(m, read_external_loads(g + "ExperimentalData/subject01_walk_grf.xml"),
                           read_storage(g + "ExperimentalData/subject01_walk_grf.mot"));
  const auto tasks = read_cmc_tasks(g + "gait10dof_Kinematics_Tracking_Tasks.xml");
  const Storage kin = read_storage(g + "RRA/Results/subject_adjusted_Kinematics_q.sto");
  ComputedMuscleControlOptions o;
  o.time_range_s = std::make_pair(0.6, 1.9);
  o.window_s = 0.005;
  double simulated = 0;
  for (auto _ : state) {
    const auto r = computed_muscle_control(m, kin, &loads, nullptr, acts, tasks, nullptr, o);
    simulated += r.summary.simulated_s;
  }
  state.counters["simulated_s_per_s"] = benchmark::Counter(simulated, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CmcGait10dof18muscMillard)->Unit(benchmark::kSecond)->Iterations(10);  // 0.1 s each: ten for a steadier rate

// The reproduced gait on subject01, one thread: a CPG fitted to OpenSim 4.1's static-optimization
// activations drives the muscles on contact spheres (fitted to the trial) for two gait cycles.
// Counter: simulated seconds per wall-clock second (the issue's target: 10). Argument 0: rigid
// tendons (the default), 1: compliant.
static void BM_ReproducedGaitSubject01(benchmark::State& state) {
  const std::string pl = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  const std::string so = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim41-here/SO/subject01_walk1_StaticOptimization_activation.sto";
  if (!std::filesystem::exists(so) || !std::filesystem::exists(pl + "subject01_walk1.trc")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim41-here or opensim/gait2392/pipeline");
    return;
  }
  const std::string generic = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/model/gait2392_simbody.osim";
  if (!std::filesystem::exists(generic)) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392/model");
    return;
  }
  // Muscle lengths scaled from the generic model, as the reproduced-gait test does.
  const Model m = scale_muscle_parameters(read_osim(pl + "OutputReference/subject01_simbody.osim").model, read_osim(generic).model);
  const Storage act = read_storage(so), grf = read_storage(pl + "subject01_walk1_grf.mot");
  // The reference: IK of the whole trial, as the reproduced-gait test does (two cycles fit in it).
  const IkResult ik = inverse_kinematics(m, read_trc(pl + "subject01_walk1.trc"), read_ik_setup(pl + "subject01_Setup_IK.xml").tasks);
  const Storage kin = ik_coordinates_table(m, ik);
  const std::vector<double> strikes = contact_onsets(grf.time(), grf.data.col(grf.column("ground_force_vy")));
  const Eigen::VectorXd t = act.time();
  const std::vector<double> time(t.data(), t.data() + t.size());
  std::vector<std::string> names;
  Eigen::MatrixXd patterns(act.num_rows(), m.muscles.size());
  for (std::size_t k = 0; k < m.muscles.size(); ++k) {
    names.push_back(m.muscles[k].name);
    patterns.col(k) = act.data.col(act.column(m.muscles[k].name));
  }
  const double cycle_s = mean_cycle_duration(time, strikes);
  const CpgFitResult fit = fit_cpg(cycle_average(time, patterns, strikes, 100), cycle_s, names);
  ContactSet feet = default_foot_contacts(m);
  fit_foot_spheres_to_trial(m, feet, ik.time_s, ik.q);
  ReproducedGaitOptions o;
  o.start_time_s = heel_strikes_zeni(m, ik.time_s, ik.q, "calcn_r").front();
  o.duration_s = 2 * cycle_s;
  o.compliant_tendons = state.range(0) == 1;
  if (state.range(0) >= 2) {
    // Closed loop (issue 22): no residuals, reflexes on the cycle at the CPG's phase, the balance
    // feedback on at the tuner's starting gains; the first 1.5 s, which it walks untuned.
    o.pelvis_residuals = false;
    o.phase_indexed_reference = true;
    o.balance = {2.0, 2.0, 0.3, 0.1, 0.5, 0.0};
    o.duration_s = 1.5;
  }
  if (state.range(0) == 3) o.control_interval_s = 0.001, o.integrator = WMethod::kRos2;  // the defaults before ROS34PW2 at 2.5 ms
  if (state.range(0) == 4) o.integrator = WMethod::kLinearlyImplicitEuler;  // one step per 2.5 ms interval
  double simulated = 0;
  for (auto _ : state) simulated += reproduce_gait(m, fit.model, kin, feet, o).time_s.back();
  state.counters["simulated_s_per_s"] = benchmark::Counter(simulated, benchmark::Counter::kIsRate);
}
// Args: 0 rigid tendons with residuals, 1 compliant tendons, 2 the closed loop without residuals, 3 the
// same with ROS2 at a 1 ms controller interval (the defaults before ROS34PW2 at 2.5 ms), 4 the same
// with the linearly implicit Euler method (the gait stage's "integrator": "linearly_implicit_euler").
BENCHMARK(BM_ReproducedGaitSubject01)->Unit(benchmark::kSecond)->Iterations(2)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Arg(4);

// Runs the pipeline on `in` with `options` into a temporary folder, then replays for 10 s on one
// thread, as `cpgait gait` replays it, the controller it tuned (walk_cpg_tuned.json against
// `reference`, a file of that run) on model m: the controller's feet fitted to the trial's, its gains
// and start. Counters: simulated seconds per wall-clock second (issue 22's target: 30), falls.
static void replay_tuned_walk(benchmark::State& state, const services::TrialInputs& in, const services::PipelineOptions& options, const Model& m,
                              const std::string& reference, const std::string& folder) {
  const std::string out = (std::filesystem::temp_directory_path() / folder).string();
  services::run_pipeline(in, options, out);
  const CpgModel cpg = CpgModel::from_json(nlohmann::json::parse(text::read_file(out + "/walk_cpg_tuned.json")), "walk_cpg_tuned.json");
  const Storage kin = read_storage(out + "/" + reference);
  std::filesystem::remove_all(out);
  ContactSet feet = default_foot_contacts(m, cpg.controller->foot_spheres);
  const CoordinateTrajectories k = coordinate_trajectories(m, kin, {});
  fit_foot_spheres_to_trial(m, feet, k.recorded_time_s, k.q_recorded);
  ReproducedGaitOptions o = with_controller(*cpg.controller, ReproducedGaitOptions{});
  o.pelvis_residuals = false;
  o.duration_s = 10;
  double simulated = 0, fell = 0;
  for (auto _ : state) {
    const ReproducedGaitResult r = reproduce_gait(m, cpg, kin, feet, o);
    simulated += r.time_s.back();
    fell += r.fell_at_s >= 0;
  }
  state.counters["simulated_s_per_s"] = benchmark::Counter(simulated, benchmark::Counter::kIsRate);
  state.counters["falls"] = fell;
}

// The autonomous gait on subject01 (gait2392: 23 coordinates, 92 Thelen muscles, rigid tendons) with
// the gait stage's "integrator": "linearly_implicit_euler", one thread: the stage's knob-1 controller
// at its defaults otherwise (604 simulations, about 40 s on 2 cores before timing; it walks 10 s)
// replayed for 10 s as `replay_tuned_walk` says. With ROS34PW2, the default, the same tuning took 2.5
// times as long on the same day (docs/gait-speed.md).
static void BM_ReproducedGaitSubject01Tuned(benchmark::State& state) {
  const std::string pl = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  const std::string generic = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/model/gait2392_simbody.osim";
  if (!std::filesystem::exists(pl + "subject01_walk1.trc") || !std::filesystem::exists(generic)) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  services::TrialInputs in;
  in.name = "walk";
  in.model_path = pl + "OutputReference/subject01_simbody.osim";
  in.generic_model_path = generic;
  in.markers = text::read_file(pl + "subject01_walk1.trc"), in.markers_name = "subject01_walk1.trc";
  in.grf = text::read_file(pl + "subject01_walk1_grf.mot"), in.grf_name = "subject01_walk1_grf.mot";
  in.loads = text::read_file(pl + "subject01_walk1_grf.xml"), in.loads_name = "subject01_walk1_grf.xml";
  services::PipelineOptions options = services::PipelineOptions::from_json(
      nlohmann::json::parse(R"({"gait": {"integrator": "linearly_implicit_euler", "speed_knobs": [], "check_tolerances": []}})"), "bench");
  options.set_stage_option("ik", "tasks", nlohmann::json::parse(ik_tasks_json(read_ik_tasks(pl + "subject01_Setup_IK.xml"))), "bench");
  const Model m = scale_muscle_parameters(read_osim(in.model_path).model, read_osim(generic).model);
  replay_tuned_walk(state, in, options, m, "walk_gait_reference.sto", "cpgait_bench_subject01");
}
BENCHMARK(BM_ReproducedGaitSubject01Tuned)->Unit(benchmark::kSecond)->Iterations(3);

// The autonomous gait on gait10dof18musc (planar, 18 Millard muscles, rigid tendons), one thread: the
// controller the pipeline's gait stage tunes (here in 120 simulations, about 20 s on 2 cores before
// timing; it walks 10 s) replayed for 10 s as `cpgait gait` replays it. Counter: simulated seconds
// per wall-clock second (issue 22's target: 30). Argument 0: the stage's defaults (2.5 ms controller
// interval, tolerance 1e-3); 1: tuned and walked at 5 ms and 2e-3 (docs/gait-speed.md); 2: tuned and
// walked with the linearly implicit Euler method at 2.5 ms.
static void BM_ReproducedGaitGait10dof18musc(benchmark::State& state) {
  const std::string d = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait10dof18musc/";
  if (!std::filesystem::exists(d + "OutputReference/subject01.osim") || !std::filesystem::exists(d + "IK/walk_Setup_IK.xml")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait10dof18musc");
    return;
  }
  services::TrialInputs in;
  in.name = "walk";
  in.model_path = d + "OutputReference/subject01.osim";
  in.markers = text::read_file(d + "ExperimentalData/subject01_walk.trc"), in.markers_name = "subject01_walk.trc";
  in.grf = text::read_file(d + "ExperimentalData/subject01_walk_grf.mot"), in.grf_name = "subject01_walk_grf.mot";
  in.loads = text::read_file(d + "ExperimentalData/subject01_walk_grf.xml"), in.loads_name = "subject01_walk_grf.xml";
  services::PipelineOptions options = services::PipelineOptions::from_json(
      nlohmann::json::parse(R"({"gait": {"residuals": false, "phase_reference": true, "tune_evaluations": 120, "tune_horizon_s": 10,
        "tune_rounds": 1, "duration_s": 10, "foot_spheres": 2, "tune_restarts": 0, "tune_rotation_limit_deg": 0, "tune_stop_at": [],
        "speed_knobs": [], "check_tolerances": []}})"),
      "bench");
  if (state.range(0) == 1) {
    options.set_stage_option("gait", "control_interval_s", 0.005, "bench");
    options.set_stage_option("gait", "tolerance", 0.002, "bench");
  }
  if (state.range(0) == 2) options.set_stage_option("gait", "integrator", "linearly_implicit_euler", "bench");
  options.set_stage_option("ik", "tasks", nlohmann::json::parse(ik_tasks_json(read_ik_tasks(d + "IK/walk_Setup_IK.xml"))), "bench");
  replay_tuned_walk(state, in, options, read_osim(in.model_path).model, "walk_ik.mot", "cpgait_bench_gait10dof");
}
BENCHMARK(BM_ReproducedGaitGait10dof18musc)->Unit(benchmark::kSecond)->Iterations(3)->Arg(0)->Arg(1)->Arg(2);
