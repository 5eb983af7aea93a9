// The service's pipeline end to end on subject01 (IK, ID and SO over 0.5-2.5 s, files written), one
// thread: trials per second. The API load test reports its wall time; this is where throughput is held.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "pipeline.h"
#include "subject01_trial.h"

using namespace cpgait;

static void BM_PipelineIkIdSoSubject01(benchmark::State& state) {
  services::TrialInputs in;
  if (!bench::subject01_trial(in)) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const services::PipelineOptions options =
      services::PipelineOptions::from_json({{"stages", {"ik", "id", "so"}}, {"time_range", {0.5, 2.5}}}, "bench");
  const std::string out = (std::filesystem::temp_directory_path() / "cpgait_bench_pipeline").string();
  int trials = 0;
  for (auto _ : state) {
    services::run_pipeline(in, options, out);
    ++trials;
  }
  std::filesystem::remove_all(out);
  state.counters["trials/s"] = benchmark::Counter(trials, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PipelineIkIdSoSubject01)->Unit(benchmark::kMillisecond)->MinTime(2.0);
