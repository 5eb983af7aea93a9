// Static optimization throughput on one thread: gait2392 (92 muscles; also with 40+ wrap cylinders)
// and arm26 (wrapping). Frames per second.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/activation/static_optimization.h"
#include "cpgait/model/osim_reader.h"
#include "wrapped_gait2392.h"

using namespace cpgait;

static void so_subject01(benchmark::State& state, Model (*modify)(Model)) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model read = read_osim(base + "OutputReference/subject01_simbody.osim").model;
  const Model model = modify ? modify(read) : read;
  const ResolvedActuators acts(model, read_actuators(base + "gait2392_SO_weak_Residual_Actuators.xml"));
  const AppliedLoads loads(model, read_external_loads(base + "subject01_walk1_grf.xml"), read_storage(base + "subject01_walk1_grf.mot"));
  const Storage coords = read_storage(base + "subject01_walk1_ik.mot");
  StaticOptimizationOptions o;
  o.lowpass_cutoff_hz = 6;
  o.time_range_s = std::make_pair(0.5, 2.0);
  int frames = 0;
  for (auto _ : state) {
    const StaticOptimizationResult r = static_optimization(model, coords, &loads, acts, o);
    frames += r.summary.frames;
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}

static void BM_SoGait2392Subject01(benchmark::State& state) { so_subject01(state, nullptr); }
BENCHMARK(BM_SoGait2392Subject01)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The same with a wrap cylinder at every hip and knee each muscle crosses (40+ wrap objects).
static void BM_SoGait2392WrapCylinders(benchmark::State& state) { so_subject01(state, bench::gait2392_with_wrap_cylinders); }
BENCHMARK(BM_SoGait2392WrapCylinders)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// arm26 (six muscles over four wrap cylinders and two ellipsoids), OpenSim's SO test setup's inputs:
// the IK motion at 6 Hz, no external loads, the model's own actuators.
static void BM_SoArm26Wrapping(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/opensim-core-tests/Analyze/";
  if (!std::filesystem::exists(base + "arm26.osim")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/opensim-core-tests/Analyze");
    return;
  }
  const Model model = read_osim(base + "arm26.osim").model;
  const ResolvedActuators acts(model, read_actuators(base + "arm26.osim"));
  const Storage coords = read_storage(base + "arm26_InverseKinematics.mot");
  StaticOptimizationOptions o;
  o.lowpass_cutoff_hz = 6;
  int frames = 0;
  for (auto _ : state) {
    const StaticOptimizationResult r = static_optimization(model, coords, nullptr, acts, o);
    frames += r.summary.frames;
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SoArm26Wrapping)->Unit(benchmark::kMillisecond)->MinTime(1.0);

// Millard2012EquilibriumMuscle on OpenSim's SO test with an ankle CoordinateLimitForce
// (subject01_adjusted_spring: 18 Millard muscles, 10 actuators, GRF, every 10th row as the setup).
static void BM_SoMillardAnkleSpring(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/opensim-core-tests/Analyze/";
  if (!std::filesystem::exists(base + "subject01_adjusted_spring.osim")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/opensim-core-tests/Analyze");
    return;
  }
  const Model model = read_osim(base + "subject01_adjusted_spring.osim").model;
  const ResolvedActuators acts(model, read_actuators(base + "subject01_adjusted_spring.osim"));
  const AppliedLoads loads(model, read_external_loads(base + "externalForces.xml"), read_storage(base + "subject01_walk1_grf.mot"));
  const Storage coords = read_storage(base + "walk_subject01_Kinematics_q.sto");
  StaticOptimizationOptions o;
  o.time_range_s = std::make_pair(0.5, 1.3);
  o.step_interval = 10;
  int frames = 0;
  for (auto _ : state) {
    const StaticOptimizationResult r = static_optimization(model, coords, &loads, acts, o);
    frames += r.summary.frames;
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SoMillardAnkleSpring)->Unit(benchmark::kMillisecond)->MinTime(1.0);
