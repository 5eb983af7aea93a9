// C3D parsing throughput on the vendors' files in ../shared (Vicon, Qualisys, BTS), one thread: MB/s.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/ground_reactions.h"
#include "cpgait/capture/marker_file.h"
#include "cpgait/capture/storage.h"
#include "cpgait/capture/text_lines.h"

using namespace cpgait;

// The vendors' files present in ../shared; none: the benchmark is skipped.
static std::vector<std::string> vendor_files(benchmark::State& state, std::initializer_list<const char*> names) {
  const std::string dir = std::string(CPGAIT_SHARED_DIR) + "/reference/c3d/";
  std::vector<std::string> files;
  for (const char* f : names)
    if (std::filesystem::exists(dir + f)) files.push_back(text::read_file(dir + f));
  if (files.empty()) state.SkipWithError("reference data absent: ../shared/reference/c3d");
  return files;
}

static void BM_C3dParseVendorFiles(benchmark::State& state) {
  const std::vector<std::string> files = vendor_files(state, {"Vicon.c3d", "Qualisys.c3d", "BTS.c3d"});
  if (files.empty()) return;
  std::size_t bytes = 0;
  for (auto _ : state)
    for (const std::string& f : files) {
      benchmark::DoNotOptimize(parse_c3d(f, "bench.c3d"));
      bytes += f.size();
    }
  state.counters["MB/s"] = benchmark::Counter(static_cast<double>(bytes) / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_C3dParseVendorFiles)->Unit(benchmark::kMillisecond)->MinTime(1.0);

// The whole conversion of the files with force plates (Qualisys, BTS): parse, markers to OpenSim's
// frame, plates to the GRF table and loads, both formatted as the files `cpgait convert` writes.
static void BM_C3dConvertWithForcePlates(benchmark::State& state) {
  const std::vector<std::string> files = vendor_files(state, {"Qualisys.c3d", "BTS.c3d"});
  if (files.empty()) return;
  std::size_t bytes = 0;
  for (auto _ : state)
    for (const std::string& f : files) {
      const C3dFile file = parse_c3d(f, "bench.c3d");
      const Eigen::Matrix3d r = c3d_to_opensim(file, C3dVertical::kAuto);
      MarkerTrial markers = file.markers;
      markers.positions_m = r * markers.positions_m;
      const GroundReactions g = ground_reactions(file, r);
      benchmark::DoNotOptimize(format_trc(markers, "mm").size() + format_storage(g.grf).size() +
                               external_loads_document(g, "bench_grf.mot").size());
      bytes += f.size();
    }
  state.counters["MB/s"] = benchmark::Counter(static_cast<double>(bytes) / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_C3dConvertWithForcePlates)->Unit(benchmark::kMillisecond)->MinTime(1.0);
