// C3D parsing throughput on the vendors' files in ../shared (Vicon, Qualisys, BTS), one thread: MB/s.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "cpgait/capture/c3d.h"
#include "cpgait/capture/text_lines.h"

using namespace cpgait;

static void BM_C3dParseVendorFiles(benchmark::State& state) {
  const std::string dir = std::string(CPGAIT_SHARED_DIR) + "/reference/c3d/";
  std::vector<std::string> files;
  for (const char* f : {"Vicon.c3d", "Qualisys.c3d", "BTS.c3d"})
    if (std::filesystem::exists(dir + f)) files.push_back(text::read_file(dir + f));
  if (files.empty()) {
    state.SkipWithError("reference data absent: ../shared/reference/c3d");
    return;
  }
  std::size_t bytes = 0;
  for (auto _ : state)
    for (const std::string& f : files) {
      benchmark::DoNotOptimize(parse_c3d(f, "bench.c3d"));
      bytes += f.size();
    }
  state.counters["MB/s"] = benchmark::Counter(static_cast<double>(bytes) / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_C3dParseVendorFiles)->Unit(benchmark::kMillisecond)->MinTime(1.0);
