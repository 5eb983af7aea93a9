// ID throughput on one thread: RNEA with ground reaction forces, frames per second.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/model/osim_reader.h"

using namespace cpgait;

static void BM_IdGait2392Subject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model model = read_osim(base + "OutputReference/subject01_simbody.osim").model;
  const AppliedLoads loads(model, read_external_loads(base + "subject01_walk1_grf.xml"),
                           read_storage(base + "subject01_walk1_grf.mot"));
  const Storage coords = read_storage(base + "subject01_walk1_ik.mot");
  InverseDynamicsOptions o;
  o.lowpass_cutoff_hz = 6;
  // Filtering and differentiation once; the loop measures the per-frame dynamics.
  const InverseDynamicsResult pre = inverse_dynamics(model, coords, &loads, o);
  const auto& k = pre.kinematics;
  DynamicsWorkspace ws(model);
  KinematicsWorkspace<double> kin(model);
  std::vector<Vector6d> external(model.bodies.size());
  Eigen::VectorXd q(model.num_coordinates()), qd(q.size()), qdd(q.size()), tau(q.size());
  int frames = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < k.time_s.size(); ++i) {
      q = k.q.row(i).transpose();
      qd = k.qd.row(i).transpose();
      qdd = k.qdd.row(i).transpose();
      forward_kinematics(model, q.data(), kin);
      loads.wrenches_at(k.time_s[i], kin, external);
      rnea(model, q.data(), qd.data(), qdd.data(), external, ws, tau.data());
      benchmark::DoNotOptimize(tau.data());
      ++frames;
    }
  }
  state.counters["frames/s"] = benchmark::Counter(frames, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_IdGait2392Subject01)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

// The whole stage including filtering, splines and output, per trial.
static void BM_IdStageGait2392Subject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  if (!std::filesystem::exists(base + "subject01_walk1_grf.mot")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return;
  }
  const Model model = read_osim(base + "OutputReference/subject01_simbody.osim").model;
  const AppliedLoads loads(model, read_external_loads(base + "subject01_walk1_grf.xml"),
                           read_storage(base + "subject01_walk1_grf.mot"));
  const Storage coords = read_storage(base + "subject01_walk1_ik.mot");
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
