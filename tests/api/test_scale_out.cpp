// Scale-out on PostgreSQL: one API server, several `cpgait worker` processes, a shared data folder.
// Each test starts a PostgreSQL server of its own (tests/postgres/pg_test_server.sh), as one of them
// restarts it; they skip where the Debian package postgresql is not installed.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <set>

#include "api_helpers.h"
#include "server_process.h"
#include "sha256.h"
#include "sql_connection.h"

namespace fs = std::filesystem;
using namespace cpgait::apitest;

namespace {

#define START_POSTGRES(pg)                                                                                             \
  cpgait::testing::PrivatePostgres pg;                                                                                     \
  if (pg.url().empty()) GTEST_SKIP() << "PostgreSQL server not installed (Debian package postgresql): scale-out untested"

// The workers' log lines saying a trial finished done: trial id -> how many times.
std::map<std::string, int> done_lines(const std::vector<std::string>& logs) {
  std::map<std::string, int> n;
  for (const auto& log : logs) {
    std::istringstream lines(log);
    for (std::string line; std::getline(lines, line);) {
      const json j = json::parse(line, nullptr, false);
      if (j.is_object() && j.value("event", "") == "trial" && j.value("state", "") == "done") n[j["trial"]]++;
    }
  }
  return n;
}

std::map<std::string, std::string> files_of(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out[e.path().filename().string()] = slurp(e.path().string());
  return out;
}

// job.json without where the inputs were (the service's own copies, its model by id).
std::string job_without_inputs(const std::string& text) {
  json j = json::parse(text);
  j.erase("inputs");
  j.erase("model");
  return j.dump();
}

int count_status(httplib::Client& c, const std::string& status) {
  auto r = c.Get(("/api/v1/trials?limit=1&status=" + status).c_str());
  return r && r->status == 200 ? body(r)["total"].get<int>() : -1;
}

// Waits until `want` trials are done; false at the deadline.
bool wait_all_done(const std::function<httplib::Client&()>& client, int want, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    if (count_status(client(), "done") == want) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

}  // namespace

// Acceptance 1: 200 trials through one API server and three workers: each done once, each result
// the bytes `cpgait run` writes for the same inputs, each checksum recorded.
TEST(ScaleOut, ThreeWorkersRunTwoHundredTrialsOnceEachAsCpgaitRunDoes) {
  const std::string dir = cpgait::refdata::temp_dir("scale_out_200");
  START_POSTGRES(pg);
  const std::string data = dir + "/data";
  ServerProcess api(data, {"--workers", "0"}, pg.url());
  std::vector<std::unique_ptr<WorkerProcess>> workers;
  for (int i = 0; i < 3; ++i) workers.push_back(std::make_unique<WorkerProcess>(data, pg.url(), std::vector<std::string>{"--name", "worker" + std::to_string(i)}));
  // Four different synthetic walks, each uploaded 50 times; each also run by `cpgait run`.
  std::vector<std::string> trcs;
  for (int k = 0; k < 4; ++k) {
    trcs.push_back(synthetic_trc(1.0, 10 + k));
    const std::string in = dir + "/walk" + std::to_string(k) + ".trc";
    std::ofstream(in) << trcs.back();
    ASSERT_EQ(std::system((std::string(CPGAIT_BINARY) + " run --model " + cpgait::refdata::fixture("models/walker.osim") + " --markers " + in +
                           " -o " + dir + "/cli" + std::to_string(k) + " > /dev/null 2>&1")
                              .c_str()),
              0);
  }
  httplib::Client c("127.0.0.1", api.port());
  std::map<std::string, int> walk_of;  // trial id -> k
  std::string last;
  for (int i = 0; i < 200; ++i) {
    const int k = i % 4;
    auto r = c.Post("/api/v1/trials", trial_form(trcs[static_cast<std::size_t>(k)], "walk" + std::to_string(k) + ".trc", {{"model", "walker"}}));
    ASSERT_TRUE(r && r->status == 202) << (r ? r->body : "no answer");
    walk_of[body(r)["id"]] = k;
    last = body(r)["id"];
  }
  // Server-Sent Events from the API server follow a trial that a worker process runs (the last one
  // queued, still waiting when the stream opens).
  int progress_events = 0;
  EXPECT_EQ(follow_events(c, last, &progress_events), "done");
  EXPECT_GT(progress_events, 0);
  ASSERT_TRUE(wait_all_done([&]() -> httplib::Client& { return c; }, 200, 600)) << count_status(c, "done") << " done";
  EXPECT_EQ(count_status(c, "failed"), 0);

  std::vector<std::string> logs;
  for (auto& w : workers) logs.push_back(w->log());
  const auto done = done_lines(logs);
  EXPECT_EQ(done.size(), 200u);
  for (const auto& [id, n] : done) EXPECT_EQ(n, 1) << id << " finished " << n << " times";
  for (int i = 0; i < 3; ++i) EXPECT_NE(logs[static_cast<std::size_t>(i)].find("\"state\":\"done\""), std::string::npos) << "worker" << i << " ran nothing";

  // Results: the CLI's bytes, and the checksums the finishing transaction recorded.
  auto db = cpgait::services::open_postgres(pg.url());
  std::map<std::string, json> checksums;
  for (const auto& row : db->query("SELECT id, checksums, attempt FROM trials")) {
    checksums[*row[0]] = json::parse(*row[1]);
    EXPECT_EQ(*row[2], "1") << *row[0] << " ran more than once";
  }
  for (const auto& [id, k] : walk_of) {
    const auto served = files_of(data + "/trials/" + id + "/results");
    const auto cli = files_of(dir + "/cli" + std::to_string(k));
    ASSERT_EQ(served.size(), cli.size()) << id;
    for (const auto& [name, bytes] : cli) {
      ASSERT_TRUE(served.count(name)) << name;
      if (name == "job.json") EXPECT_EQ(job_without_inputs(served.at(name)), job_without_inputs(bytes));
      else EXPECT_EQ(served.at(name), bytes) << id << "/" << name << " differs from cpgait run's";
      EXPECT_EQ(checksums[id].value(name, ""), cpgait::services::sha256_hex(served.at(name))) << id << "/" << name;
    }
  }
  const std::string metrics = c.Get("/metrics")->body;
  EXPECT_NE(metrics.find("cpgait_trials{status=\"done\"} 200"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cpgait_queue_depth 0"), std::string::npos) << metrics;
  EXPECT_NE(metrics.find("cpgait_stage_seconds_count{stage=\"ik\"} 200"), std::string::npos) << metrics;
  workers.clear();
  fs::remove_all(dir);
}

// Acceptance 2: kill -9 a worker in the middle of a trial, twice, and the API server once: every
// trial completes exactly once, nothing finished is rewritten, a dead worker's trial is re-queued
// once its lease runs out.
TEST(ScaleOut, KilledWorkersAndServerLoseNoTrialAndRewriteNoResult) {
  const std::string dir = cpgait::refdata::temp_dir("scale_out_kill");
  START_POSTGRES(pg);
  const std::string data = dir + "/data";
  const double lease_s = 3, heartbeat_s = 0.5;
  const std::vector<std::string> lease_args = {"--lease", "3", "--heartbeat", "0.5"};
  auto api = std::make_unique<ServerProcess>(data, std::vector<std::string>{"--workers", "0", "--lease", "3", "--heartbeat", "0.5"}, pg.url());
  auto worker = [&](const std::string& name) {
    auto args = lease_args;
    args.insert(args.end(), {"--name", name});
    return std::make_unique<WorkerProcess>(data, pg.url(), args);
  };
  std::vector<std::unique_ptr<WorkerProcess>> workers;
  std::vector<std::string> logs;  // of stopped workers
  auto client = [&]() -> httplib::Client& {
    static std::unique_ptr<httplib::Client> c;
    static int port = 0;
    if (!c || port != api->port()) c = std::make_unique<httplib::Client>("127.0.0.1", port = api->port());
    return *c;
  };
  // Ten-second walks: a second or more each with the CPG and the reproduced gait.
  const std::string trc = synthetic_trc(10.0, 5);
  int n = 0;  // trials uploaded
  auto upload = [&] {
    auto r = client().Post("/api/v1/trials", trial_form(trc, "long" + std::to_string(n++) + ".trc", walker_with_residual_gait()));
    ASSERT_TRUE(r && r->status == 202);
  };
  for (int i = 0; i < 18; ++i) upload();
  auto db = cpgait::services::open_postgres(pg.url());
  std::map<std::string, std::pair<std::string, fs::file_time_type>> finished;  // result file -> (bytes, mtime)
  auto snapshot_finished = [&] {
    for (const auto& row : db->query("SELECT id FROM trials WHERE status = 'done'"))
      for (const auto& e : fs::directory_iterator(data + "/trials/" + *row[0] + "/results"))
        if (!finished.count(e.path().string())) finished[e.path().string()] = {slurp(e.path().string()), e.last_write_time()};
  };
  // Kills a worker as soon as it holds a trial and starts a replacement; records in recovery_s how long
  // until that trial ran again. A trial takes about half a second, so the worker may finish it between
  // the poll and the kill: then nothing was orphaned, three more trials are queued, and the next holder
  // is killed, up to five times.
  std::vector<std::string> names = {"a", "b", "c"};  // of the live workers, by index
  for (const auto& name : names) workers.push_back(worker(name));
  std::vector<double> recovery_s;
  auto kill_mid_trial = [&] {
    for (int attempt = 1;; ++attempt) {
      std::string name;
      std::size_t index = 0;
      const auto wait_until = std::chrono::steady_clock::now() + std::chrono::seconds(120);
      while (name.empty()) {
        ASSERT_LT(std::chrono::steady_clock::now(), wait_until) << "no worker held a trial";
        for (const auto& row : db->query("SELECT worker FROM trials WHERE status = 'running'")) {
          const auto live = std::find(names.begin(), names.end(), *row[0]);
          if (live != names.end()) name = *live, index = static_cast<std::size_t>(live - names.begin());
        }
        if (name.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      const std::string held = "SELECT id, attempt FROM trials WHERE status = 'running' AND worker = '" + name + "'";
      workers[index]->stop(SIGKILL);
      const auto killed = std::chrono::steady_clock::now();
      const auto orphans = db->query(held);  // what the dead worker held when it died
      ASSERT_LE(orphans.size(), 1u) << name << " held two trials";
      snapshot_finished();
      logs.push_back(workers[index]->log());
      names[index] = name + "2";
      workers[index] = worker(names[index]);
      if (orphans.empty()) {
        ASSERT_LT(attempt, 5) << "the killed worker was between trials five times running";
        for (int i = 0; i < 3; ++i) upload();
        continue;
      }
      const std::string id = *orphans[0][0], attempt_held = *orphans[0][1];
      // No trial stays running once its lease is over: it is re-queued (and re-claimed) within a heartbeat.
      while (db->query("SELECT id FROM trials WHERE id = '" + id + "' AND attempt = " + attempt_held + " AND status = 'running'").size() == 1) {
        ASSERT_LT(std::chrono::steady_clock::now() - killed, std::chrono::duration<double>(lease_s + 4 * heartbeat_s + 2))
            << "trial " << id << " of a dead worker still held";
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      recovery_s.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - killed).count());
      return;
    }
  };
  kill_mid_trial();
  if (HasFatalFailure()) return;
  // The API server dies too; uploads and reads resume on its replacement.
  api->stop(SIGKILL);
  api = std::make_unique<ServerProcess>(data, std::vector<std::string>{"--workers", "0", "--lease", "3", "--heartbeat", "0.5"}, pg.url());
  ASSERT_EQ(client().Get("/api/v1/trials?limit=1")->status, 200);
  kill_mid_trial();
  if (HasFatalFailure()) return;

  ASSERT_TRUE(wait_all_done(client, n, 600)) << count_status(client(), "done") << " of " << n << " done";
  for (auto& w : workers) logs.push_back(w->log());
  const auto done = done_lines(logs);
  EXPECT_EQ(done.size(), static_cast<std::size_t>(n));
  for (const auto& [id, k] : done) EXPECT_EQ(k, 1) << id << " finished " << k << " times";
  EXPECT_GE(std::stoi(*db->query("SELECT value FROM counters WHERE name = 'lease_expiries'")[0][0]), 2);
  for (const auto& [path, before] : finished) {
    EXPECT_EQ(slurp(path), before.first) << path << " was rewritten";
    EXPECT_EQ(fs::last_write_time(path), before.second) << path << " was touched";
  }
  for (const auto& row : db->query("SELECT id FROM trials"))
    for (const auto& e : fs::directory_iterator(data + "/trials/" + *row[0]))
      EXPECT_EQ(e.path().filename().string().rfind("work", 0), std::string::npos) << e.path() << " left behind";
  EXPECT_NE(client().Get("/metrics")->body.find("cpgait_lease_expiries_total "), std::string::npos);
  std::printf("[ info ] not asserted beyond the lease bound: lease %.1f s, heartbeat %.1f s; a killed worker's trial went back to the "
              "queue %.2f s and %.2f s after the kill; %zu finished result files unchanged\n",
              lease_s, heartbeat_s, recovery_s.at(0), recovery_s.at(1), finished.size());
  workers.clear();
  api.reset();
  fs::remove_all(dir);
}

// Acceptance 3: PostgreSQL restarts in the middle of the run; workers and the API server reconnect.
TEST(ScaleOut, PostgresRestartLosesNoTrial) {
  const std::string dir = cpgait::refdata::temp_dir("scale_out_pg_restart");
  START_POSTGRES(pg);
  const std::string data = dir + "/data";
  ServerProcess api(data, {"--workers", "0"}, pg.url());
  std::vector<std::unique_ptr<WorkerProcess>> workers;
  for (const char* name : {"x", "y"}) workers.push_back(std::make_unique<WorkerProcess>(data, pg.url(), std::vector<std::string>{"--name", name}));
  httplib::Client c("127.0.0.1", api.port());
  const std::string trc = synthetic_trc(10.0, 6);
  const int n = 10;
  for (int i = 0; i < n; ++i) ASSERT_EQ(c.Post("/api/v1/trials", trial_form(trc, "restart" + std::to_string(i) + ".trc", walker_with_residual_gait()))->status, 202);
  while (count_status(c, "done") < 2) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  pg.restart();
  // The API answers again (its pool reconnects), and takes uploads.
  auto after = c.Get("/api/v1/trials?limit=1");
  ASSERT_TRUE(after && after->status == 200) << (after ? after->body : "no answer");
  ASSERT_EQ(c.Post("/api/v1/trials", trial_form(trc, "late.trc", walker_with_residual_gait()))->status, 202);
  ASSERT_TRUE(wait_all_done([&]() -> httplib::Client& { return c; }, n + 1, 600)) << count_status(c, "done") << " done";
  std::vector<std::string> logs;
  for (auto& w : workers) logs.push_back(w->log());
  const auto done = done_lines(logs);
  EXPECT_EQ(done.size(), static_cast<std::size_t>(n + 1));
  for (const auto& [id, k] : done) EXPECT_EQ(k, 1) << id;
  workers.clear();
  fs::remove_all(dir);
}

// Cancel and delete through the API server reach a trial that another process runs.
TEST(ScaleOut, CancelAndDeleteReachATrialRunningInAnotherProcess) {
  const std::string dir = cpgait::refdata::temp_dir("scale_out_cancel");
  START_POSTGRES(pg);
  const std::string data = dir + "/data";
  ServerProcess api(data, {"--workers", "0"}, pg.url());
  WorkerProcess worker(data, pg.url(), {"--name", "far", "--heartbeat", "0.2"});
  httplib::Client c("127.0.0.1", api.port());
  c.set_read_timeout(60, 0);  // uploads of a ten-minute trial on a loaded machine: more than httplib's 5 s
  // Ten minutes of walking, so that the cancel and the delete reach the trial midway: a minute of it
  // now runs in well under a second, and in CI its worker once finished it before its heartbeat saw
  // the delete (abandoned at publishing, no lease_lost).
  const std::string trc = synthetic_trc(600.0, 8);
  auto running_on_worker = [&](const std::string& id) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < until) {
      const json t = body(c.Get(("/api/v1/trials/" + id).c_str()));
      if (t.value("status", "") == "running" && t.value("worker", "") == "far") return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return false;
  };
  const std::string a = body(c.Post("/api/v1/trials", trial_form(trc, "a.trc", walker_with_residual_gait())))["id"];
  ASSERT_TRUE(running_on_worker(a));
  const auto asked = std::chrono::steady_clock::now();
  const auto cancel = c.Post(("/api/v1/trials/" + a + "/cancel").c_str());
  ASSERT_TRUE(cancel) << httplib::to_string(cancel.error());
  EXPECT_EQ(cancel->status, 202);
  EXPECT_EQ(wait_finished(c, a, 30), "cancelled");
  const double cancel_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - asked).count();
  EXPECT_LT(cancel_s, 10.0) << "the worker did not see the cancel at its heartbeat";

  const std::string b = body(c.Post("/api/v1/trials", trial_form(trc, "b.trc", walker_with_residual_gait())))["id"];
  ASSERT_TRUE(running_on_worker(b));
  const auto deleted = c.Delete(("/api/v1/trials/" + b).c_str());
  ASSERT_TRUE(deleted) << httplib::to_string(deleted.error());
  EXPECT_EQ(deleted->status, 204);
  const auto gone = c.Get(("/api/v1/trials/" + b).c_str());
  ASSERT_TRUE(gone) << httplib::to_string(gone.error());
  EXPECT_EQ(gone->status, 404);
  // The worker drops the trial at its next heartbeat and leaves no folder behind.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (worker.log().find("\"abandoned\"") == std::string::npos && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  // The heartbeat's path (lease_lost) wherever the run outlived two heartbeats; a run that ended
  // sooner (in CI once 12 ms after the delete took its folder) is abandoned at publishing alone.
  double ran_s = -1;
  std::istringstream lines(worker.log());
  for (std::string line; std::getline(lines, line);) {
    const json e = json::parse(line, nullptr, false);
    if (e.is_object() && e.value("trial", "") == b && e.value("state", "") == "abandoned") ran_s = e.value("seconds", -1.0);
  }
  EXPECT_GE(ran_s, 0.0) << "no abandoned run of " << b << ": " << worker.log();
  if (ran_s >= 0.4) {
    EXPECT_NE(worker.log().find("\"lease_lost\""), std::string::npos) << worker.log();
  }
  EXPECT_FALSE(fs::exists(data + "/trials/" + b));
  std::printf("[ info ] cancel reached the worker's trial in %.2f s (heartbeat 0.2 s); the deleted one ran %.2f s\n", cancel_s, ran_s);
  fs::remove_all(dir);
}
