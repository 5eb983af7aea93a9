// ID throughput on one thread: RNEA with ground reaction forces, frames per second.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>

#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/osim_reader.h"

using namespace cpgait;

namespace {
// OpenSim's subject01 inputs for ID; skips the benchmark when ../shared is absent.
struct Subject01 {
  Model model;
  AppliedLoads loads;
  Storage coordinates;
  static std::unique_ptr<Subject01> load(benchmark::State& state) {
    const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
    if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
      state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
      return nullptr;
    }
    Model m = read_osim(base + "OutputReference/subject01_simbody.osim").model;
    AppliedLoads l(m, read_external_loads(base + "subject01_walk1_grf.xml"), read_storage(base + "subject01_walk1_grf.mot"));
    return std::unique_ptr<Subject01>(new Subject01{std::move(m), std::move(l), read_storage(base + "subject01_walk1_ik.mot")});
  }
};
}  // namespace

static void BM_IdGait2392Subject01(benchmark::State& state) {
  const std::unique_ptr<Subject01> d = Subject01::load(state);
  if (!d) return;
  const Model& model = d->model;
  const AppliedLoads& loads = d->loads;
  const Storage& coords = d->coordinates;
  InverseDynamicsOptions o;
  o.lowpass_cutoff_hz = 6;
  // Filtering and differentiation once; the loop measures the per-frame dynamics.
  const InverseDynamicsResult pre = inverse_dynamics(model, coords, &loads, o);
  const auto& k = pre.kinematics;
  InverseDynamicsFrameWorkspace ws(model);
  Eigen::VectorXd q(model.num_coordinates()), qd(q.size()), qdd(q.size()), tau(q.size());
  int frames = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < k.time_s.size(); ++i) {
      q = k.q.row(i).transpose();
      qd = k.qd.row(i).transpose();
      qdd = k.qdd.row(i).transpose();
      inverse_dynamics_frame(model, q.data(), qd.data(), qdd.data(), k.time_s[i], &loads, ws, tau.data());
      benchmark::DoNotOptimize(tau.data());
      ++frames;
    }
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IdGait2392Subject01)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The whole stage including filtering, splines and output, per trial.
static void BM_IdStageGait2392Subject01(benchmark::State& state) {
  const std::unique_ptr<Subject01> d = Subject01::load(state);
  if (!d) return;
  const Model& model = d->model;
  const AppliedLoads& loads = d->loads;
  const Storage& coords = d->coordinates;
  InverseDynamicsOptions o;
  o.lowpass_cutoff_hz = 6;
  int frames = 0;
  for (auto _ : state) {
    const InverseDynamicsResult r = inverse_dynamics(model, coords, &loads, o);
    frames += r.summary.frames;
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IdStageGait2392Subject01)->Unit(benchmark::kMillisecond)->MinTime(1.0);
