// IK throughput on one thread: frames per second over a whole trial (counter "frames/s").
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/capture/ik_setup.h"
#include "cpgait/fixtures/synthetic_trial.h"
#include "cpgait/ik/inverse_kinematics.h"
#include "cpgait/model/osim_reader.h"

using namespace cpgait;

static void BM_IkGait2392Subject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1.trc")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model model = read_osim(base + "OutputReference/subject01_simbody.osim").model;
  const MarkerTrial trial = read_trc(base + "subject01_walk1.trc");
  const IkSetup setup = read_ik_setup(base + "subject01_Setup_IK.xml");
  IkOptions o;
  o.time_range_s = setup.time_range_s;
  int frames = 0;
  for (auto _ : state) {
    IkResult r = inverse_kinematics(model, trial, setup.tasks, o);
    frames += r.summary.frames;
    benchmark::DoNotOptimize(r.q.data());
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IkGait2392Subject01)->Unit(benchmark::kMillisecond)->MinTime(2.0);

static void BM_IkWalkerSynthetic(benchmark::State& state) {
  const Model model = read_osim(std::string(CPGAIT_FIXTURES_DIR) + "/models/walker.osim").model;
  fixtures::SyntheticTrialOptions so;
  so.noise_m = 0.001;
  const auto synth = fixtures::synthesize_trial(model, so);
  int frames = 0;
  for (auto _ : state) {
    IkResult r = inverse_kinematics(model, synth.markers, {});
    frames += r.summary.frames;
    benchmark::DoNotOptimize(r.q.data());
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IkWalkerSynthetic)->Unit(benchmark::kMillisecond)->MinTime(2.0);

