// Big jobs (issue #25, item 5): a job of 1,000,000 bands and one of
// 10,000 frames are taken in bounded work. The coordinator keeps a few
// bytes per queued band in memory and nothing per band in the store until
// the band is leased; its status is the job's counters, not a walk over its
// bands. Times and memory are measured by bench/farm/big_jobs.sh, not here:
// these tests check the work done.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <string>

#include "common/scene/scene_io.h"
#include "server/coordinator.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {

namespace fs = std::filesystem;
using test_doubles::TempDir;
using test_doubles::TestWorker;

const std::string kSpheres = std::string(LOCUS_SOURCE_DIR) + "/scenes/simple/spheres.json";

SubmitRequest big_job(int frames, int bands, int height) {
  auto scene = load_scene(kSpheres);
  EXPECT_TRUE(scene.ok());
  SubmitRequest r;
  r.scene = scene_to_proto(*scene);
  r.scene_name = kSpheres;
  r.width = 8;
  r.height = height;
  r.frame_first = 1;
  r.frame_last = frames;
  r.bands = bands;
  r.output = "f_#####.png";
  r.render.aa = 0;
  return r;
}

// Rows of a table of the store, through a connection of our own.
int64_t rows(const fs::path& data, const std::string& table) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2((data / "locus.db").c_str(), &db, SQLITE_OPEN_READONLY, nullptr),
            SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  const std::string sql = std::string("SELECT COUNT(*) FROM ").append(table);
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr), SQLITE_OK) << sqlite3_errmsg(db);
  int64_t n = -1;
  if (sqlite3_step(st) == SQLITE_ROW) n = sqlite3_column_int64(st, 0);
  sqlite3_finalize(st);
  sqlite3_close(db);
  return n;
}

class BigJobs : public ::testing::Test {
 protected:
  BigJobs() {
    CoordinatorOptions o = test_doubles::test_options(dir.path);
    o.cost_bands = false;  // equal heights: 100 bands of one row
    c = std::make_unique<Coordinator>(o);
    EXPECT_TRUE(c->start().ok());
  }
  ~BigJobs() override { c->shutdown(); }
  fs::path data() const { return dir.path / "data"; }

  TempDir dir;
  std::unique_ptr<Coordinator> c;
};

TEST_F(BigJobs, AMillionBandsAreQueuedWithoutARowPerBand) {
  auto job = c->submit(big_job(10000, 100, 100));
  ASSERT_TRUE(job.ok()) << job.status().message();
  EXPECT_EQ(job->spec.bands_total(), 1000000);
  // Nothing per band in the store yet: the job's record and a few lines.
  EXPECT_EQ(rows(data(), "jobs"), 1);
  EXPECT_EQ(rows(data(), "bands"), 0);
  EXPECT_EQ(rows(data(), "attempts"), 0);
  EXPECT_LT(rows(data(), "history"), 10);
  // Its status and the list are the job's counters.
  auto status = c->job(job->job_id);
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status->state, JobState::kQueued);
  EXPECT_EQ(status->bands_done, 0);
  EXPECT_TRUE(status->frames_written.empty());
  ASSERT_EQ(c->jobs().size(), 1u);
  // A worker's band: one attempt row, one band record once accepted; the
  // other 999,999 bands still have none.
  TestWorker w(*c, "w");
  auto lease = w.take();
  ASSERT_TRUE(lease);
  EXPECT_EQ(lease->frame, 1);
  EXPECT_EQ(lease->y1 - lease->y0, 1);
  ASSERT_TRUE(w.complete(*lease));
  EXPECT_EQ(rows(data(), "attempts"), 1);
  EXPECT_EQ(rows(data(), "bands"), 1);
  status = c->job(job->job_id);
  ASSERT_TRUE(status.ok());
  EXPECT_EQ(status->bands_done, 1);
  EXPECT_EQ(status->state, JobState::kRunning);
  // Cancelled, it keeps what its history needs and queues nothing.
  ASSERT_TRUE(c->cancel(job->job_id).ok());
  EXPECT_EQ(rows(data(), "bands"), 1);
  EXPECT_FALSE(c->metrics_text().empty());
}

TEST_F(BigJobs, TenThousandFramesFinishFramesAsTheyComeAndKeepNoPixels) {
  auto job = c->submit(big_job(10000, 2, 2));
  ASSERT_TRUE(job.ok()) << job.status().message();
  EXPECT_EQ(rows(data(), "bands"), 0);
  TestWorker w(*c, "w");
  // The first three frames: leased in order, written as they complete,
  // their pixels gone from the store once written.
  for (int i = 0; i < 6; ++i) {
    auto lease = w.take();
    ASSERT_TRUE(lease);
    EXPECT_EQ(lease->frame, 1 + i / 2);
    ASSERT_TRUE(w.complete(*lease));
  }
  JobInfo status;
  for (int i = 0; i < 500; ++i) {
    status = *c->job(job->job_id);
    if (status.frames_done == 3) break;
    std::this_thread::sleep_for(Millis(10));
  }
  EXPECT_EQ(status.frames_done, 3);
  EXPECT_EQ(status.frames_written, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(status.bands_done, 6);
  EXPECT_EQ(rows(data(), "band_pixels"), 0);
  EXPECT_EQ(rows(data(), "bands"), 6);  // the history: each band's outcome
  EXPECT_EQ(rows(data(), "attempts"), 6);
  EXPECT_EQ(rows(data(), "frames"), 3);
}

}  // namespace
}  // namespace locus::farm
