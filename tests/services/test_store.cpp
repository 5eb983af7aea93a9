// The store on both databases: schema and migration, leases, cancel flags, concurrent claims.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

#include "postgres/test_postgres.h"
#include "sha256.h"
#include "store.h"
#include "test_support.h"

namespace fs = std::filesystem;
using cpgait::services::Store;
using cpgait::services::TrialRecord;
using nlohmann::json;

namespace {

TrialRecord queued_trial(const std::string& id, const std::string& created_at) {
  TrialRecord t;
  t.id = id;
  t.name = "t" + id;
  t.status = "queued";
  t.created_at = t.updated_at = created_at;
  t.options = {{"model", "walker"}};
  t.stages = {{"ik"}, {"id"}, {"so", "skipped"}};
  return t;
}

std::string hex_id(int i) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016x", i);
  return buf;
}

}  // namespace

TEST(Sha256, MatchesFips180Vectors) {
  using cpgait::services::sha256_hex;
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(sha256_hex(std::string(1000000, 'a')), "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// Every padding case (tails of 0-63 bytes, one or two final blocks) against coreutils' sha256sum.
TEST(Sha256, AgreesWithSha256sumAtEveryTailLength) {
  const std::string dir = cpgait::refdata::temp_dir("sha256");
  for (int n = 0; n <= 130; ++n) {
    std::string bytes;
    for (int i = 0; i < n; ++i) bytes += static_cast<char>((i * 131 + n) & 0xff);
    const std::string path = dir + "/b" + std::to_string(n);
    std::ofstream(path, std::ios::binary) << bytes;
    FILE* p = popen(("sha256sum " + path).c_str(), "r");
    ASSERT_NE(p, nullptr);
    char out[65] = {};
    ASSERT_EQ(std::fread(out, 1, 64, p), 64u);
    pclose(p);
    EXPECT_EQ(cpgait::services::sha256_hex(bytes), std::string(out)) << n << " bytes";
  }
  fs::remove_all(dir);
}

// A store written by cpgait before schema versions (the first release's tables) opens migrated.
TEST(StoreMigration, UnversionedSqliteStoreIsMigratedWhenOpened) {
  const std::string dir = cpgait::refdata::temp_dir("store_migrate");
  const std::string path = dir + "/cpgait.sqlite";
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "CREATE TABLE trials (id TEXT PRIMARY KEY, name TEXT, status TEXT NOT NULL, created_at TEXT, updated_at TEXT, "
                         "options TEXT, error TEXT);"
                         "CREATE INDEX trials_status ON trials(status, created_at);"
                         "CREATE TABLE stages (trial_id TEXT NOT NULL, position INTEGER, name TEXT NOT NULL, state TEXT, progress REAL, "
                         "seconds REAL, summary TEXT, PRIMARY KEY (trial_id, name));"
                         "CREATE TABLE models (id TEXT PRIMARY KEY, name TEXT, created_at TEXT, warnings TEXT, summary TEXT);"
                         "INSERT INTO trials VALUES ('00000000000000aa', 'old', 'done', '2026-01-01T00:00:00.000Z', "
                         "'2026-01-01T00:00:01.000Z', '{\"model\":\"walker\"}', NULL);"
                         "INSERT INTO trials VALUES ('00000000000000bb', 'waiting', 'queued', '2026-01-02T00:00:00.000Z', "
                         "'2026-01-02T00:00:00.000Z', '{}', NULL);"
                         "INSERT INTO stages VALUES ('00000000000000aa', 0, 'ik', 'done', 1.0, 0.25, '{\"rms_mm\":1.5}');",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);

  Store store("sqlite:" + path);
  EXPECT_EQ(store.schema_version(), Store::kSchemaVersion);
  const auto old = store.trial("00000000000000aa");
  ASSERT_TRUE(old);
  EXPECT_EQ(old->status, "done");
  ASSERT_EQ(old->stages.size(), 1u);
  EXPECT_EQ(old->stages[0].summary["rms_mm"], 1.5);
  EXPECT_EQ(old->attempt, 0);
  // The queued one runs under the new schema's lease.
  const auto claimed = store.claim_next("w", 30);
  ASSERT_TRUE(claimed);
  EXPECT_EQ(claimed->id, "00000000000000bb");
  EXPECT_EQ(claimed->attempt, 1);

  // A store from a newer cpgait is refused, not damaged.
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE schema_version SET version = 99", nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  try {
    Store newer("sqlite:" + path);
    ADD_FAILURE() << "a store of schema 99 was opened";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// The same behaviour on both stores.
class StoreOn : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "postgresql") {
      REQUIRE_POSTGRES();
      const std::string name = std::string("store_") + ::testing::UnitTest::GetInstance()->current_test_info()->name();
      std::string db;
      for (char c : name) db += std::isalnum(static_cast<unsigned char>(c)) ? static_cast<char>(std::tolower(c)) : '_';
      spec_ = cpgait::testing::fresh_postgres_database(db.substr(0, 60));
    } else {
      dir_ = cpgait::refdata::temp_dir("store_on_sqlite");
      spec_ = "sqlite:" + dir_ + "/cpgait.sqlite";
    }
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  std::string spec_, dir_;
};

TEST_P(StoreOn, LeasesHandEachTrialToOneWorkerAndExpireBackToTheQueue) {
  Store store(spec_);
  EXPECT_EQ(store.schema_version(), Store::kSchemaVersion);
  for (int i = 0; i < 3; ++i) store.insert_trial(queued_trial(hex_id(i), "2026-01-01T00:00:0" + std::to_string(i) + ".000Z"));
  const auto a = store.claim_next("A", 60), b = store.claim_next("B", 60), c = store.claim_next("C", 0.2);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(a->id, hex_id(0));  // oldest first
  EXPECT_EQ(b->id, hex_id(1));
  EXPECT_EQ(c->id, hex_id(2));
  EXPECT_FALSE(store.claim_next("D", 60));
  EXPECT_EQ(store.renew_lease(a->id, "A", 1, 60), Store::Lease::kHeld);
  EXPECT_EQ(store.renew_lease(a->id, "B", 1, 60), Store::Lease::kLost) << "another worker's lease was renewed";

  // C stops renewing: its trial goes back to the queue, counted; A's and B's do not.
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  EXPECT_EQ(store.requeue_expired(), std::vector<std::string>{c->id});
  EXPECT_EQ(store.metrics().lease_expiries, 1);
  EXPECT_EQ(store.trial(c->id)->status, "queued");
  EXPECT_EQ(store.renew_lease(c->id, "C", 1, 60), Store::Lease::kLost);
  const auto again = store.claim_next("D", 60);
  ASSERT_TRUE(again);
  EXPECT_EQ(again->id, c->id);
  EXPECT_EQ(again->attempt, 2);

  // The late worker C can neither write stages nor publish.
  store.set_stage(c->id, 1, {"ik", "done", 1, 9.0, json::object()});
  EXPECT_EQ(store.trial(c->id)->stages[0].state, "pending");
  bool published = false;
  EXPECT_FALSE(store.finish_trial(c->id, "C", 1, "done", nullptr, json::object(), [&] { published = true; }));
  EXPECT_FALSE(published);
  // D finishes it, once.
  store.set_stage(c->id, 2, {"ik", "done", 1, 0.5, {{"frames", 3}}});
  EXPECT_TRUE(store.finish_trial(c->id, "D", 2, "done", nullptr, {{"t_ik.mot", "ab"}}, [&] { published = true; }));
  EXPECT_TRUE(published);
  EXPECT_FALSE(store.finish_trial(c->id, "D", 2, "done", nullptr, json::object(), [] {})) << "finished twice";
  const auto done = store.trial(c->id);
  EXPECT_EQ(done->status, "done");
  EXPECT_EQ(done->stages[0].summary["frames"], 3);
  EXPECT_TRUE(done->worker.empty());

  // A fails: its unfinished stages say so.
  store.set_stage(a->id, 1, {"ik", "running", 0.5, 0, json::object()});
  EXPECT_TRUE(store.finish_trial(a->id, "A", 1, "failed", {{"code", "stage_failed"}}, nullptr, [] {}));
  const auto failed = store.trial(a->id);
  EXPECT_EQ(failed->stages[0].state, "failed");
  EXPECT_EQ(failed->stages[1].state, "skipped");
  EXPECT_EQ(failed->error["code"], "stage_failed");

  const auto m = store.metrics();
  EXPECT_EQ(m.trials_by_status.at("running"), 1);
  EXPECT_EQ(m.running_by_worker.at("B"), 1);
  EXPECT_EQ(m.stage_seconds.at("ik").second, 1);
  EXPECT_DOUBLE_EQ(m.stage_seconds.at("ik").first, 0.5);
}

TEST_P(StoreOn, CancelIsImmediateWhenQueuedAndAFlagTheWorkerSeesWhenRunning) {
  Store store(spec_);
  store.insert_trial(queued_trial(hex_id(1), "2026-01-01T00:00:01.000Z"));
  store.insert_trial(queued_trial(hex_id(2), "2026-01-01T00:00:02.000Z"));
  const auto running = store.claim_next("W", 60);
  ASSERT_TRUE(running);
  EXPECT_EQ(store.request_cancel(hex_id(2)), Store::Cancel::kCancelled);
  EXPECT_EQ(store.trial(hex_id(2))->status, "cancelled");
  EXPECT_EQ(store.request_cancel(running->id), Store::Cancel::kCancelling);
  EXPECT_EQ(store.renew_lease(running->id, "W", 1, 60), Store::Lease::kCancelRequested);
  // A cancelled trial is not handed back to the queue on shutdown.
  store.release_trial(running->id, "W", 1);
  EXPECT_EQ(store.trial(running->id)->status, "running");
  EXPECT_TRUE(store.finish_trial(running->id, "W", 1, "cancelled", nullptr, nullptr, [] {}));
  EXPECT_EQ(store.request_cancel(running->id), Store::Cancel::kFinished);
  EXPECT_EQ(store.request_cancel("ffffffffffffffff"), Store::Cancel::kFinished);
  EXPECT_TRUE(store.delete_trial(running->id));
  EXPECT_FALSE(store.trial(running->id));
}

TEST_P(StoreOn, PublishThatThrowsLeavesTheTrialRunning) {
  Store store(spec_);
  store.insert_trial(queued_trial(hex_id(7), "2026-01-01T00:00:00.000Z"));
  const auto t = store.claim_next("W", 60);
  ASSERT_TRUE(t);
  EXPECT_THROW(store.finish_trial(t->id, "W", 1, "done", nullptr, json::object(), [] { throw std::runtime_error("disk full"); }),
               std::runtime_error);
  EXPECT_EQ(store.trial(t->id)->status, "running");
  EXPECT_TRUE(store.finish_trial(t->id, "W", 1, "done", nullptr, json::object(), [] {}));
}

// Four processes' worth of connections claiming at once: every trial exactly once.
TEST_P(StoreOn, ConcurrentClaimsNeverShareATrial) {
  {
    Store store(spec_);
    for (int i = 0; i < 120; ++i) store.insert_trial(queued_trial(hex_id(i), "2026-01-01T00:00:00.000Z"));
  }
  std::vector<std::vector<std::string>> got(4);
  std::vector<std::thread> workers;
  for (int w = 0; w < 4; ++w)
    workers.emplace_back([&, w] {
      static const char* names[] = {"W0", "W1", "W2", "W3"};
      Store store(spec_, 1);
      while (auto t = store.claim_next(names[w], 60)) got[w].push_back(t->id);
    });
  for (auto& t : workers) t.join();
  std::set<std::string> all;
  std::size_t total = 0;
  for (const auto& g : got) {
    total += g.size();
    all.insert(g.begin(), g.end());
  }
  EXPECT_EQ(total, 120u);
  EXPECT_EQ(all.size(), 120u);
}

INSTANTIATE_TEST_SUITE_P(, StoreOn, ::testing::Values("sqlite", "postgresql"), [](const auto& info) { return info.param; });
