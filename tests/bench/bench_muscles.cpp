// Muscle-path geometry (lengths, speeds, moment arms) per frame over a recorded motion: arm26 with its
// wrap cylinders, gait2392's 92 straight-line paths, and gait2392 with a cylinder at every hip and
// knee each muscle crosses. Counters: frames/s, muscle paths/s, and the share of paths that wrap.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>

#include "cpgait/dynamics/inverse_dynamics.h"
#include "cpgait/kinematics/forward_kinematics.h"
#include "cpgait/kinematics/motion_subspace.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/muscles/muscle_path.h"
#include "wrapped_gait2392.h"

using namespace cpgait;

static void muscle_paths(benchmark::State& state, const std::string& model_path, const std::string& motion_path,
                         Model (*modify)(Model) = nullptr) {
  if (!std::filesystem::exists(model_path) || !std::filesystem::exists(motion_path)) {
    state.SkipWithError(("reference data absent: " + model_path).c_str());
    return;
  }
  const Model model = modify ? modify(read_osim(model_path).model) : read_osim(model_path).model;
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
  // How much of the work was wrapping: paths that touch a surface, over the motion.
  long wrapping = 0;
  std::vector<PathVertex<double>> path;
  for (int i = 0; i < static_cast<int>(k.time_s.size()); ++i) {
    const Eigen::VectorXd q = k.q.row(i).transpose();
    forward_kinematics(model, q.data(), ws);
    for (const Muscle& mu : model.muscles) {
      current_path(model, mu, q.data(), ws, path);
      wrapping += std::any_of(path.begin(), path.end(), [](const PathVertex<double>& v) { return v.wrap >= 0; });
    }
  }
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
  state.counters["paths/s"] =
      benchmark::Counter(static_cast<double>(frames) * static_cast<double>(model.muscles.size()), benchmark::Counter::kIsRate);
  state.counters["wrap objects"] = static_cast<double>(model.wrap_objects.size());
  state.counters["wrapping %"] = 100.0 * static_cast<double>(wrapping) / static_cast<double>(k.time_s.size() * model.muscles.size());
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

// gait2392 with 40+ wrap objects (tests/bench/wrapped_gait2392.h) over subject01's walk.
static void BM_MusclePathsGait2392WrapCylinders(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/pipeline/";
  muscle_paths(state, base + "OutputReference/subject01_simbody.osim", base + "subject01_walk1_ik.mot", bench::gait2392_with_wrap_cylinders);
}
BENCHMARK(BM_MusclePathsGait2392WrapCylinders)->Unit(benchmark::kMillisecond)->MinTime(1.0);
