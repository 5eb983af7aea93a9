// Static optimization throughput on one thread with all 92 muscles: frames per second.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/activation/static_optimization.h"
#include "cpgait/model/osim_reader.h"

using namespace cpgait;

static void BM_SoGait2392Subject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model model = read_osim(base + "OutputReference/subject01_simbody.osim").model;
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
BENCHMARK(BM_SoGait2392Subject01)->Unit(benchmark::kMillisecond)->MinTime(2.0);
