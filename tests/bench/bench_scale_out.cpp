// Scale-out throughput: one API server (no local workers) and N `cpgait worker` processes on a
// PostgreSQL server of the benchmark's own, the built-in walker's synthetic 5 s walks (every stage).
// Reports trials per minute and the p95 latency of GET /trials/{id} polled while they run.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <memory>

#include "api/api_helpers.h"
#include "api/server_process.h"

using namespace cpgait::apitest;

static void BM_ScaleOutWorkers(benchmark::State& state) {
  const std::string dir = cpgait::refdata::temp_dir("bench_scale_out");
  cpgait::testing::PrivatePostgres pg;
  if (pg.url().empty()) {
    state.SkipWithError("PostgreSQL server not installed (Debian package postgresql)");
    return;
  }
  const int workers_n = static_cast<int>(state.range(0)), trials = 24;
  const std::string data = dir + "/data";
  ServerProcess api(data, {"--workers", "0"}, pg.url());
  std::vector<std::unique_ptr<WorkerProcess>> workers;
  for (int i = 0; i < workers_n; ++i) workers.push_back(std::make_unique<WorkerProcess>(data, pg.url()));
  const std::string trc = synthetic_trc(5.0, 3);
  httplib::Client c("127.0.0.1", api.port());
  std::vector<double> latency_ms;
  double minutes = 0;
  int done_total = 0;
  for (auto _ : state) {
    std::vector<std::string> ids;
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < trials; ++i) ids.push_back(body(c.Post("/api/v1/trials", trial_form(trc, "walk.trc", {{"model", "walker"}})))["id"]);
    int done = 0;
    while (done < trials) {
      done = 0;
      for (const auto& id : ids) {
        const auto t0 = std::chrono::steady_clock::now();
        auto r = c.Get(("/api/v1/trials/" + id).c_str());
        latency_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        done += r && body(r)["status"] == "done";
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    minutes += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() / 60;
    done_total += done;
  }
  std::sort(latency_ms.begin(), latency_ms.end());
  state.counters["trials/min"] = done_total / minutes;
  state.counters["get_p95_ms"] = latency_ms[latency_ms.size() * 95 / 100];
  state.counters["get_p50_ms"] = latency_ms[latency_ms.size() / 2];
  workers.clear();
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_ScaleOutWorkers)->Arg(1)->Arg(2)->Arg(3)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();
