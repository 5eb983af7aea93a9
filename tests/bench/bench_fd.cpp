// Forward dynamics on one thread: evaluations of qdd = M^-1 (tau - bias) per second on gait2392.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "cpgait/dynamics/forward_dynamics.h"
#include "cpgait/model/osim_reader.h"

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
