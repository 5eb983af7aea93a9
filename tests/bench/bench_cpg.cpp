// The CPG fit on subject01's static-optimization activations over its right gait cycle (the pipeline's
// cpg stage): seconds per fit (all cores) and the mean R^2 over the active muscles.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>

#include "cpgait/capture/storage.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/model/osim_reader.h"
#include "pipeline.h"
#include "subject01_trial.h"

using namespace cpgait;

static void BM_CpgFitSubject01(benchmark::State& state) {
  services::TrialInputs in;
  if (!bench::subject01_trial(in)) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  // The activations as the pipeline makes them (IK, ID, SO), once.
  const std::string out = (std::filesystem::temp_directory_path() / "cpgait_bench_cpg").string();
  services::run_pipeline(in, services::PipelineOptions::from_json({{"stages", {"ik", "id", "so"}}}, "bench"), out);
  const Storage activations = read_storage(out + "/subject01_walk1_StaticOptimization_activation.sto");
  std::filesystem::remove_all(out);
  std::vector<std::string> names;
  std::vector<int> cols;
  for (const auto& m : read_osim(in.model_path).model.muscles) {
    const int c = activations.column(m.name);
    if (c > 0) names.push_back(m.name), cols.push_back(c);
  }
  Eigen::MatrixXd patterns(activations.num_rows(), static_cast<Eigen::Index>(cols.size()));
  for (std::size_t k = 0; k < cols.size(); ++k) patterns.col(static_cast<Eigen::Index>(k)) = activations.data.col(cols[k]);
  const Storage grf = parse_storage(in.grf, in.grf_name);
  const std::vector<double> starts = contact_onsets(grf.time(), grf.data.col(grf.column("ground_force_vy")));
  const Eigen::VectorXd t = activations.time();
  const std::vector<double> time(t.data(), t.data() + t.size());
  const CpgFitOptions options;
  const Eigen::MatrixXd cycle = cycle_average(time, patterns, starts, options.phase_samples);
  const double cycle_s = mean_cycle_duration(time, starts);
  double r2 = 0;
  for (auto _ : state) r2 = fit_cpg(cycle, cycle_s, names, options).summary.mean_r_squared_active;
  state.counters["mean_R2"] = r2;
  state.counters["muscles"] = static_cast<double>(names.size());
}
BENCHMARK(BM_CpgFitSubject01)->Unit(benchmark::kSecond)->Iterations(2)->UseRealTime();
