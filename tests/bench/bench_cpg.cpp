// The CPG fit on subject01's static-optimization activations over its right gait cycle (the pipeline's
// cpg stage): seconds per fit (all cores) and the mean R^2 over the active muscles.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "cpgait/capture/storage.h"
#include "cpgait/cpg/cpg_fit.h"
#include "cpgait/model/osim_reader.h"
#include "pipeline.h"
#include "subject01_trial.h"

using namespace cpgait;

namespace {

// subject01's muscles and their cycle-averaged activations over its right gait cycle, as the
// pipeline makes them (IK, ID, SO), computed once.
struct Subject01Cycle {
  std::vector<std::string> names;
  Eigen::MatrixXd cycle;  // phase samples x muscles
  double cycle_s = 0;
  bool present = false;
};

const Subject01Cycle& subject01_cycle() {
  static const Subject01Cycle c = [] {
    Subject01Cycle r;
    services::TrialInputs in;
    if (!bench::subject01_trial(in)) return r;
    const std::string out = (std::filesystem::temp_directory_path() / "cpgait_bench_cpg").string();
    services::run_pipeline(in, services::PipelineOptions::from_json({{"stages", {"ik", "id", "so"}}}, "bench"), out);
    const Storage activations = read_storage(out + "/subject01_walk1_StaticOptimization_activation.sto");
    std::filesystem::remove_all(out);
    std::vector<int> cols;
    for (const auto& m : read_osim(in.model_path).model.muscles) {
      const int col = activations.column(m.name);
      if (col > 0) r.names.push_back(m.name), cols.push_back(col);
    }
    Eigen::MatrixXd patterns(activations.num_rows(), static_cast<Eigen::Index>(cols.size()));
    for (std::size_t k = 0; k < cols.size(); ++k) patterns.col(static_cast<Eigen::Index>(k)) = activations.data.col(cols[k]);
    const Storage grf = parse_storage(in.grf, in.grf_name);
    const std::vector<double> starts = contact_onsets(grf.time(), grf.data.col(grf.column("ground_force_vy")));
    const Eigen::VectorXd t = activations.time();
    const std::vector<double> time(t.data(), t.data() + t.size());
    r.cycle = cycle_average(time, patterns, starts, CpgFitOptions{}.phase_samples);
    r.cycle_s = mean_cycle_duration(time, starts);
    r.present = true;
    return r;
  }();
  return c;
}

}  // namespace

static void BM_CpgFitSubject01(benchmark::State& state) {
  const Subject01Cycle& c = subject01_cycle();
  if (!c.present) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  double r2 = 0;
  for (auto _ : state) r2 = fit_cpg(c.cycle, c.cycle_s, c.names, CpgFitOptions{}).summary.mean_r_squared_active;
  state.counters["mean_R2"] = r2;
  state.counters["muscles"] = static_cast<double>(c.names.size());
}
BENCHMARK(BM_CpgFitSubject01)->Unit(benchmark::kSecond)->Iterations(2)->UseRealTime();

// A walk of 11 cycles (13.6 s) made from subject01's: each cycle 3 % longer or shorter than the last
// and its activations perturbed by 5 % (deterministic), at 100 Hz; the fit averages the cycles first.
static void BM_CpgFitWalk11Cycles(benchmark::State& state) {
  const Subject01Cycle& c = subject01_cycle();
  if (!c.present) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const int cycles = 11, S = static_cast<int>(c.cycle.rows());
  std::vector<double> starts{0.0}, time;
  for (int k = 0; k < cycles; ++k) starts.push_back(starts.back() + c.cycle_s * (1 + 0.03 * std::sin(1.7 * k)));
  for (double t = 0; t <= starts.back(); t += 0.01) time.push_back(t);
  Eigen::MatrixXd patterns(static_cast<Eigen::Index>(time.size()), c.cycle.cols());
  for (std::size_t i = 0; i < time.size(); ++i) {
    const std::size_t k = std::min<std::size_t>(std::upper_bound(starts.begin(), starts.end(), time[i]) - starts.begin() - 1, cycles - 1);
    const double phase = (time[i] - starts[k]) / (starts[k + 1] - starts[k]) * S;
    const int j = static_cast<int>(phase) % S;
    patterns.row(static_cast<Eigen::Index>(i)) = c.cycle.row(j) * (1 + 0.05 * std::sin(0.37 * static_cast<double>(i)));
  }
  double r2 = 0;
  for (auto _ : state) {
    const Eigen::MatrixXd cycle = cycle_average(time, patterns, starts, CpgFitOptions{}.phase_samples);
    r2 = fit_cpg(cycle, mean_cycle_duration(time, starts), c.names, CpgFitOptions{}).summary.mean_r_squared_active;
  }
  state.counters["mean_R2"] = r2;
  state.counters["seconds_of_walking"] = starts.back();
}
BENCHMARK(BM_CpgFitWalk11Cycles)->Unit(benchmark::kSecond)->Iterations(2)->UseRealTime();
