// The service's pipeline end to end on subject01 (IK, ID and SO over 0.5-2.5 s, files written), one
// thread: trials per second. The API load test reports its wall time; this is where throughput is held.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/capture/text_lines.h"
#include "pipeline.h"

using namespace cpgait;

static void BM_PipelineIkIdSoSubject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  services::TrialInputs in;
  in.name = "subject01_walk1";
  in.model_path = base + "OutputReference/subject01_simbody.osim";
  in.markers = text::read_file(base + "subject01_walk1.trc"), in.markers_name = "subject01_walk1.trc";
  in.grf = text::read_file(base + "subject01_walk1_grf.mot"), in.grf_name = "subject01_walk1_grf.mot";
  in.loads = text::read_file(base + "subject01_walk1_grf.xml"), in.loads_name = "subject01_walk1_grf.xml";
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
