// The coordinator's syncs, counted in the process (server/syncs.h): SQLite's
// through the counting VFS, exactly as many as its synchronous setting asks
// for; the coordinator's own for a durable band and its frame; and the
// same counts in the Prometheus series.
#include "server/syncs.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <string>

#include "server/coordinator.h"
#include "server/store.h"
#include "tests/farm_fixture.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
using test_doubles::TempDir;
using test_doubles::TestWorker;
using testing_farm::kSpheres;
using testing_farm::request;

void exec(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  ASSERT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err), SQLITE_OK) << (err ? err : "");
}

// SQLite's syncs per commit in WAL mode: none under synchronous=OFF or
// NORMAL (until a checkpoint), one per commit under FULL (the WAL's), plus
// at most one for the WAL's header when the log starts.
TEST(Syncs, SqlitesSyncsAreCountedAsItsSettingAsksForThem) {
  count_store_syncs();
  TempDir dir;
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((dir.path / "t.db").c_str(), &db), SQLITE_OK);
  exec(db, "PRAGMA journal_mode=WAL");
  exec(db, "PRAGMA wal_autocheckpoint=0");
  exec(db, "CREATE TABLE t(x)");
  for (const auto& [setting, low, high] :
       {std::tuple{"OFF", 0, 0}, std::tuple{"NORMAL", 0, 0}, std::tuple{"FULL", 10, 11}}) {
    SCOPED_TRACE(setting);
    exec(db, std::string("PRAGMA synchronous=") + setting);
    const SyncCounts before = sync_counts();
    for (int i = 0; i < 10; ++i) exec(db, "INSERT INTO t VALUES (" + std::to_string(i) + ")");
    const SyncCounts after = sync_counts();
    EXPECT_GE(after.store - before.store, static_cast<uint64_t>(low));
    EXPECT_LE(after.store - before.store, static_cast<uint64_t>(high));
    EXPECT_EQ(after.files, before.files);
  }
  // A checkpoint syncs the log and then the database.
  const SyncCounts before = sync_counts();
  exec(db, "PRAGMA wal_checkpoint(TRUNCATE)");
  EXPECT_GE(sync_counts().store - before.store, 2u);
  sqlite3_close(db);
}

// One band of a one-band frame, durable: one sync of the store's log (its
// batch), the frame's file and its directory; SQLite itself syncs nothing
// under synchronous=NORMAL before a checkpoint. /metrics says the same.
TEST(Syncs, ADurableBandAndItsFrameCostThreeSyncs) {
  TempDir dir;
  CoordinatorOptions o = test_doubles::test_options(dir.path);
  o.fsync = true;
  Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  auto job = c.submit(request(kSpheres, 16, 8, 1, 1, 1, "s_####.png"));
  ASSERT_TRUE(job.ok()) << job.status().message();
  TestWorker w(c, "w:1");
  auto lease = w.take();
  ASSERT_TRUE(lease.has_value());
  const SyncCounts before = sync_counts();
  ASSERT_TRUE(w.complete(*lease));
  const JobInfo ended = test_doubles::wait_for_end(c, job->job_id);
  ASSERT_EQ(ended.state, JobState::kSucceeded) << ended.error;
  const SyncCounts after = sync_counts();
  EXPECT_EQ(after.files - before.files, 3u);
  EXPECT_EQ(after.store, before.store);
  EXPECT_EQ(c.log_syncs(), 1u);
  const std::string text = c.metrics_text();
  EXPECT_EQ(testing_farm::sample(text, "locus_syncs_total{by=\"files\"}"),
            static_cast<double>(after.files))
      << text;
  EXPECT_EQ(testing_farm::sample(text, "locus_syncs_total{by=\"store\"}"),
            static_cast<double>(after.store))
      << text;
  c.shutdown();
}

// A scene bigger than SQLite's checkpoint threshold (1000 pages of 4 KB):
// storing it checkpoints the log. A store opened to sync (a coordinator
// with --fsync, the default) syncs the log and the database then; one
// opened without (--no-fsync, the embedded farm's) syncs nothing at all.
TEST(Syncs, AStoreOpenedWithoutSyncsSyncsNothingEvenAtACheckpoint) {
  const std::string scene(6 << 20, 's');
  for (const bool sync : {true, false}) {
    SCOPED_TRACE(sync ? "sync" : "no sync");
    TempDir dir;
    auto store = JobStore::open((dir.path / "locus.db").string(), sync);
    ASSERT_TRUE(store.ok()) << store.status().message();
    const SyncCounts before = sync_counts();
    ASSERT_TRUE((*store)->put_scene("h", scene).ok());
    const uint64_t syncs = sync_counts().store - before.store;
    if (sync) {
      EXPECT_GE(syncs, 2u);
    } else {
      EXPECT_EQ(syncs, 0u);
    }
    auto back = (*store)->scene("h");
    ASSERT_TRUE(back.ok()) << back.status().message();
    EXPECT_EQ(back->size(), scene.size());
  }
  // The coordinator opens its store as its --fsync says: a job whose
  // scene is past the threshold (its first object 60,000 times over).
  TempDir dir;
  CoordinatorOptions o = test_doubles::test_options(dir.path);
  o.fsync = false;
  Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  SubmitRequest r = request(kSpheres, 16, 8, 1, 1, 1, "s_####.png");
  const v1::Object first = r.scene.objects(0);
  for (int i = 0; i < 60000; ++i) *r.scene.add_objects() = first;
  ASSERT_GT(r.scene.ByteSizeLong(), size_t{5} << 20);
  const SyncCounts before = sync_counts();
  auto job = c.submit(r);  // the scene stored before the job is
  ASSERT_TRUE(job.ok()) << job.status().message();
  EXPECT_EQ(sync_counts().total(), before.total());
  c.shutdown();
}

}  // namespace
}  // namespace locus::farm
