// Muscle-path geometry (lengths, speeds, moment arms) per frame over a recorded motion: arm26 with its
// wrap cylinders, and gait2392's 92 straight-line paths. Counters: frames/s and muscle paths/s.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_path.h"

using namespace cpgait;

static void muscle_paths(benchmark::State& state, const std::string& model_path, const std::string& motion_path) {
  if (!std::filesystem::exists(model_path) || !std::filesystem::exists(motion_path)) {
    state.SkipWithError(("reference data absent: " + model_path).c_str());
    return;
  }
  const Model model = read_osim(model_path).model;
  const CoordinateTrajectories k = coordinate_trajectories(model, read_storage(motion_path), {});
  KinematicsWorkspace<double> ws(model);
  MotionSubspace S(model);
  MusclePathGeometry g(model);
  long frames = 0;
  for (auto _ : state) {
    for (int i = 0; i < static_cast<int>(k.time_s.size()); ++i) {
      const Eigen::VectorXd q = k.q.row(i).transpose(), qd = k.qd.row(i).transpose();
      forward_kinematics(model, q.data(), ws);
      motion_subspace(model, q.data(), ws, S);
      muscle_path_geometry(model, q.data(), qd.data(), ws, S, g);
      benchmark::DoNotOptimize(g.moment_arm_m.data());
    }
    frames += static_cast<long>(k.time_s.size());
  }
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
  state.counters["paths/s"] =
      benchmark::Counter(static_cast<double>(frames) * static_cast<double>(model.muscles.size()), benchmark::Counter::kIsRate);
}

static void BM_MusclePathsArm26Wrapping(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/opensim-core-tests/Analyze/";
  muscle_paths(state, base + "arm26.osim", base + "arm26_InverseKinematics.mot");
}
BENCHMARK(BM_MusclePathsArm26Wrapping)->Unit(benchmark::kMillisecond)->MinTime(1.0);

static void BM_MusclePathsGait2392(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  muscle_paths(state, base + "OutputReference/subject01_simbody.osim", base + "subject01_walk1_ik.mot");
}
BENCHMARK(BM_MusclePathsGait2392)->Unit(benchmark::kMillisecond)->MinTime(1.0);
