// Backups of a data directory (server/backup.h), no network: taken while a
// Coordinator runs and a worker keeps returning bands, then opened by a new
// Coordinator (the restore) that must hold every band acknowledged before
// the backup began and finish every job with frames identical to one
// process; and the refusals: an existing OUT, no store, an inconsistent
// data directory (release 0.13's, as a backup before an upgrade).
// tests/backup/run.sh does the same with the processes.
#include "server/backup.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <atomic>
#include <filesystem>
#include <set>
#include <thread>
#include <tuple>

#include "common/scene/animation.h"
#include "server/band_files.h"
#include "server/coordinator.h"
#include "tests/farm_fixture.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using test_doubles::TempDir;
using test_doubles::TestWorker;
using test_doubles::wait_for_end;
using testing_farm::kSpheres;
using testing_farm::reference;
using testing_farm::request;

using BandKey = std::tuple<std::string, int, int>;  // job, frame, band

CoordinatorOptions options(const fs::path& data) {
  CoordinatorOptions o;
  o.data_dir = data.string();
  o.tick = Millis(10);
  o.fsync = false;
  return o;
}

// Whether the band is accepted (or its frame written) in the coordinator.
bool has_band(Coordinator& c, const BandKey& k) {
  const auto& [job, frame, band] = k;
  auto info = c.job(job);
  if (!info.ok()) return false;
  for (int f : info->frames_written) {
    if (f == frame) return true;
  }
  auto detail = c.frame_detail(job, frame);
  return detail.ok() && detail->bands.at(band).state == "done";
}

// Every frame equals a single-process render, decoded as written.
void expect_frames_identical(Coordinator& c, const JobInfo& job, const SubmitRequest& r,
                             const fs::path& scratch) {
  ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;
  for (int f = r.frame_first; f <= r.frame_last; ++f) {
    auto got = read_image((fs::path(c.job_dir(job.job_id)) / frame_path(r.output, f)).string());
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->rgb, reference(r, f, scratch).rgb) << job.job_id << " frame " << f;
  }
}

// Only the data and the backups: no temporary directory left beside them.
std::set<std::string> entries(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

TEST(Backup, WhileBandsAreAcceptedHoldsEveryAcknowledgedBandAndRestores) {
  TempDir dir;
  const SubmitRequest exr = request(kSpheres, 16, 12, 1, 6, 3, "f_####.exr", 40);
  const SubmitRequest png = request(kSpheres, 20, 10, 1, 4, 2, "g_####.png");
  std::set<BandKey> acknowledged;
  std::string exr_job, png_job;
  std::atomic<int> during{0};
  {
    Coordinator a(options(dir.path / "data"));
    ASSERT_TRUE(a.start().ok());
    exr_job = a.submit(exr)->job_id;
    png_job = a.submit(png)->job_id;
    TestWorker w(a, "before:1");
    for (int i = 0; i < 14; ++i) {
      auto t = w.take();
      ASSERT_TRUE(t);
      ASSERT_TRUE(w.complete(*t));
      acknowledged.insert({t->job_id, t->frame, t->band});
    }
    // The frames those bands complete are written by the coordinator's
    // writer thread (the first EXR loads the image plugin): the backup is
    // to hard-link some.
    for (int i = 0; i < 10000 && a.job(exr_job)->frames_done == 0; ++i) {
      std::this_thread::sleep_for(Millis(1));
    }
    ASSERT_GT(a.job(exr_job)->frames_done, 0);
    // Meanwhile another worker keeps returning bands, and frames are
    // written (their band files removed) while the backup runs.
    std::atomic<bool> stop{false};
    std::thread busy([&] {
      TestWorker w2(a, "during:2");
      while (!stop) {
        auto t = w2.take();
        if (!t) break;
        if (w2.complete(*t)) ++during;
        std::this_thread::sleep_for(Millis(3));
      }
    });
    for (int i = 0; i < 1000 && during == 0; ++i) std::this_thread::sleep_for(Millis(1));
    BackupOptions o;
    o.data_dir = (dir.path / "data").string();
    o.out = (dir.path / "backup").string();
    o.pages_per_step = 1;  // many steps, each between the coordinator's commits
    o.pause_ms = 2;
    auto report = backup_data_dir(o);
    stop = true;
    busy.join();
    ASSERT_TRUE(report.ok()) << report.status().message();
    EXPECT_GT(report->pages, 10);
    EXPECT_EQ(report->jobs, 2);
    EXPECT_GT(report->linked, 0);  // same filesystem: hard links
    EXPECT_EQ(report->copied, 0);
    EXPECT_GT(during.load(), 0);
    EXPECT_EQ(entries(dir.path), (std::set<std::string>{"data", "backup"}));
    EXPECT_FALSE(fs::exists(dir.path / "backup" / "coordinator.lock"));
    a.shutdown();
  }
  // The restore: a coordinator on the backup.
  Coordinator b(options(dir.path / "backup"));
  ASSERT_TRUE(b.start().ok());
  for (const BandKey& k : acknowledged) {
    EXPECT_TRUE(has_band(b, k)) << std::get<0>(k) << " frame " << std::get<1>(k) << " band "
                                << std::get<2>(k) << " was acknowledged before the backup";
  }
  TestWorker w(b, "after:3");
  while (auto t = w.take()) ASSERT_TRUE(w.complete(*t));
  expect_frames_identical(b, wait_for_end(b, exr_job), exr, dir.path);
  expect_frames_identical(b, wait_for_end(b, png_job), png, dir.path);
}

// A backup taken before an upgrade: the data directory of release 0.13
// (tests/data/store-v0.13/, j0002 with frame 1 written and band 0 of frame
// 2 in its band file), as no coordinator of this release has opened it.
class V013DataDir : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::copy(test_doubles::kStoreV013, data(), fs::copy_options::recursive);
  }
  fs::path data() const { return dir_.path / "data"; }
  fs::path band() const { return band_file_path((data() / "jobs" / kJob).string(), 2, 0); }
  fs::path frame(int f) const { return data() / "jobs" / kJob / frame_path("anim_####.exr", f); }
  Result<BackupReport> backup() const {
    BackupOptions o;
    o.data_dir = data().string();
    o.out = (dir_.path / "backup").string();
    return backup_data_dir(o);
  }
  // The backup restored, its unfinished job finished: frames identical to
  // one process.
  void expect_restores() {
    Coordinator b(options(dir_.path / "backup"));
    ASSERT_TRUE(b.start().ok());
    TestWorker w(b, "w:9");
    const JobSpec spec = b.job(kJob)->spec;
    auto held = b.get_scene(w.id, spec.scene_hash);
    ASSERT_TRUE(held.ok()) << held.status().message();
    v1::Scene scene;
    ASSERT_TRUE(scene.ParseFromString(**held));
    while (auto t = w.take()) ASSERT_TRUE(w.complete(*t));
    const JobInfo end = wait_for_end(b, kJob);
    ASSERT_EQ(end.state, JobState::kSucceeded) << end.error;
    for (int f : {1, 2}) {
      auto got = read_image((fs::path(b.job_dir(kJob)) / frame_path(spec.output, f)).string());
      ASSERT_TRUE(got.ok()) << got.status().message();
      EXPECT_EQ(got->rgb, test_doubles::single_process_frame(scene, spec, f).rgb) << f;
    }
  }

  static constexpr const char* kJob = "j0002";
  TempDir dir_;
};

TEST_F(V013DataDir, BacksUpAndRestores) {
  auto report = backup();
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->jobs, 2);
  EXPECT_EQ(report->band_files, 1);
  EXPECT_EQ(report->job_files, 3);  // shot_0001.png, shot_0002.png, anim_0001.exr
  EXPECT_TRUE(report->rendered_again.empty());
  EXPECT_TRUE(fs::exists(dir_.path / "backup" / "jobs" / kJob / "bands" / "2-0.band"));
  expect_restores();
}

TEST_F(V013DataDir, RefusesAnExistingOutOrAMissingStore) {
  fs::create_directory(dir_.path / "backup");
  auto exists = backup();
  ASSERT_FALSE(exists.ok());
  EXPECT_NE(exists.status().message().find("exists"), std::string::npos)
      << exists.status().message();
  fs::remove(dir_.path / "backup");
  fs::remove(data() / "locus.db");
  auto none = backup();
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.status().message().find("no job store"), std::string::npos)
      << none.status().message();
  EXPECT_EQ(entries(dir_.path), (std::set<std::string>{"data"}));  // nothing half-made
}

TEST_F(V013DataDir, ABandWithNeitherItsFileNorItsFrameIsAnInconsistency) {
  fs::remove(band());
  auto r = backup();
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kFailedPrecondition);
  EXPECT_NE(r.status().message().find("job j0002 frame 2 band 0 is accepted in the store"),
            std::string::npos)
      << r.status().message();
  EXPECT_NE(r.status().message().find(band().string()), std::string::npos);
  EXPECT_EQ(entries(dir_.path), (std::set<std::string>{"data"}));
}

TEST_F(V013DataDir, AWrittenFrameWithoutItsFileIsAnInconsistency) {
  fs::remove(frame(1));
  auto r = backup();
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("anim_0001.exr is recorded as written"), std::string::npos)
      << r.status().message();
  EXPECT_EQ(entries(dir_.path), (std::set<std::string>{"data"}));
}

// The race the backup tolerates: the band's file removed because its frame
// was written after the store was copied. The copy does not know the frame
// is written, so the restored coordinator renders the band again.
TEST_F(V013DataDir, ABandWhoseFrameWasWrittenMeanwhileIsRenderedAgain) {
  fs::remove(band());
  fs::copy_file(frame(1), frame(2));  // any file: it is rendered again
  auto report = backup();
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->rendered_again, std::vector<std::string>{"job j0002 frame 2 band 0"});
  expect_restores();
}

// When band pixels are kept in the store itself rather than in band files,
// a band without a file is not missing.
TEST_F(V013DataDir, PixelsHeldInTheStoreNeedNoBandFile) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((data() / "locus.db").c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db,
                         "CREATE TABLE pixels_kept(job_id TEXT, frame INTEGER, band INTEGER, "
                         "record BLOB); INSERT INTO pixels_kept VALUES('j0002', 2, 0, 'rgb')",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  fs::remove(band());
  auto report = backup();
  ASSERT_TRUE(report.ok()) << report.status().message();
  EXPECT_EQ(report->band_files, 0);
  EXPECT_TRUE(report->rendered_again.empty());
}

}  // namespace
}  // namespace locus::farm
