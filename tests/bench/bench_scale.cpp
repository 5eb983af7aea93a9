// Scaling throughput on one thread (counter "models/s"): OpenSim's Scale tool on gait2392 subject01
// from its setup - scale factors from the static trial, the scaled model, markers placed by IK on the
// static trial - and the written .osim.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <optional>

#include "cpgait/capture/scale_setup.h"
#include "cpgait/capture/trc.h"
#include "cpgait/model/osim_reader.h"
#include "cpgait/model/osim_writer.h"
#include "cpgait/scaling/fit_scale_factors.h"
#include "cpgait/scaling/model_scale_factors.h"
#include "cpgait/scaling/place_markers.h"
#include "cpgait/scaling/scale_model.h"

using namespace cpgait;

namespace {

// subject01's Scale setup, the generic gait2392 with the setup's marker set, and the static trial;
// nullopt (the benchmark skipped) when ../shared lacks them.
struct Subject01 {
  ScaleSetup setup;
  Model generic;
  MarkerTrial trial;
};
std::optional<Subject01> load_subject01(benchmark::State& state) {
  const std::string base = std::string(CPGAIT_SHARED_DIR) + "/reference/opensim/gait2392/";
  if (!std::filesystem::exists(base + "pipeline/subject01_Setup_Scale.xml")) {
    state.SkipWithError("reference data absent: ../shared/reference/opensim/gait2392");
    return std::nullopt;
  }
  Subject01 s;
  s.setup = read_scale_setup(base + "pipeline/subject01_Setup_Scale.xml");
  OsimReadOptions o;
  o.marker_set_file = base + "pipeline/" + s.setup.marker_set_file;
  s.generic = read_osim(base + "model/gait2392_simbody.osim", o).model;
  s.trial = read_trc(base + "pipeline/" + s.setup.marker_file);
  return s;
}

}  // namespace

static void BM_ScaleToolGait2392Subject01(benchmark::State& state) {
  const auto loaded = load_subject01(state);
  if (!loaded) return;
  const ScaleSetup& setup = loaded->setup;
  const Model& generic = loaded->generic;
  const MarkerTrial& trial = loaded->trial;
  const bool write = state.range(0) != 0;
  int models = 0;
  for (auto _ : state) {
    const ModelScaleFactors f = model_scale_factors(generic, setup, &trial);
    const Model scaled = scale_model(generic, f.body, setup.preserve_mass_distribution, setup.mass_kg);
    const MarkerPlacement p = place_markers(scaled, trial, setup.placer_tasks, setup.placer_time_range_s);
    if (write) benchmark::DoNotOptimize(osim_document(p.model).size());
    benchmark::DoNotOptimize(p.static_pose.data());
    ++models;
  }
  state.counters["models/s"] = benchmark::Counter(models, benchmark::Counter::kIsRate);
}
// Arg 0: scale and place; 1: also write the .osim (which reads the generic document again).
BENCHMARK(BM_ScaleToolGait2392Subject01)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Automatic scaling (no measurement set) on the same static trial, with the setup's placer weights:
// the factors, offsets and pose fitted, the model scaled and its markers placed.
static void BM_ScaleFitGait2392Subject01(benchmark::State& state) {
  const auto loaded = load_subject01(state);
  if (!loaded) return;
  const ScaleSetup& setup = loaded->setup;
  const Model& generic = loaded->generic;
  const MarkerTrial& trial = loaded->trial;
  ScaleFitOptions fo;
  fo.static_time_range_s = setup.placer_time_range_s;
  fo.subject_mass_kg = setup.mass_kg;
  int models = 0;
  for (auto _ : state) {
    const ScaleFit fit = fit_scale_factors(generic, trial, setup.placer_tasks, {}, fo);
    benchmark::DoNotOptimize(fit.static_pose.data());
    ++models;
  }
  state.counters["models/s"] = benchmark::Counter(models, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ScaleFitGait2392Subject01)->Unit(benchmark::kMillisecond)->MinTime(2.0);
