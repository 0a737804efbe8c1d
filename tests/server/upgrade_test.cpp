// A data directory written by the previous release opens in this one with
// its jobs intact (issue #25 item 6): tests/data/store-v0.13/ (its README
// says how it was made) copied to a temporary directory and opened by a
// Coordinator, no network. Strict on purpose: whatever changes how the
// store or the band pixels are kept must still read this directory.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "common/base/image.h"
#include "common/scene/animation.h"
#include "server/coordinator.h"
#include "server/store.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using test_doubles::single_process_frame;
using test_doubles::TempDir;
using test_doubles::TestWorker;
using test_doubles::wait_for_end;

const fs::path kStore = test_doubles::kStoreV013;
const std::string kFinished = "j0001", kUnfinished = "j0002";
const std::string kSpheresHash = "f4d728f33e2695ff4495f47c031b00a29457e7a4599e63a9aaa8c21f21454480";
const std::string kGlassHash = "a2a333cd2445464d6c13dbb7892766c150e3d6295441b35f02283848d4b97d64";

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The scene as v0.13 stored it, read from the committed file itself.
v1::Scene stored_scene(const std::string& hash) {
  sqlite3* db = nullptr;
  const std::string uri = "file:" + (kStore / "locus.db").string() + "?immutable=1";
  EXPECT_EQ(sqlite3_open_v2(uri.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr),
            SQLITE_OK);
  sqlite3_stmt* st = nullptr;
  sqlite3_prepare_v2(db, "SELECT scene FROM scenes WHERE hash = ?", -1, &st, nullptr);
  sqlite3_bind_text(st, 1, hash.c_str(), -1, SQLITE_TRANSIENT);
  v1::Scene scene;
  EXPECT_EQ(sqlite3_step(st), SQLITE_ROW) << hash;
  EXPECT_TRUE(scene.ParseFromArray(sqlite3_column_blob(st, 0), sqlite3_column_bytes(st, 0)));
  sqlite3_finalize(st);
  sqlite3_close(db);
  return scene;
}

// A single-process render as the file format keeps it (PNG: 8 bits).
Image as_written(const Image& image, const fs::path& path) {
  EXPECT_TRUE(write_image(path.string(), image).ok());
  auto back = read_image(path.string());
  EXPECT_TRUE(back.ok()) << back.status().message();
  return back.ok() ? *back : Image();
}

std::vector<std::string> history(Coordinator& c, const std::string& job) {
  auto lines = c.events(job, 0, 1000);
  EXPECT_TRUE(lines.ok()) << lines.status().message();
  std::vector<std::string> texts;
  if (lines.ok()) {
    for (const HistoryEntry& e : *lines) texts.push_back(e.text);
  }
  return texts;
}

class StoreV013 : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::copy(kStore, dir_.path / "data", fs::copy_options::recursive);
    c_ = std::make_unique<Coordinator>(test_doubles::test_options(dir_.path));
    const Status started = c_->start();
    ASSERT_TRUE(started.ok()) << started.message();
  }
  void TearDown() override {
    if (c_) c_->shutdown();
  }

  TempDir dir_;
  std::unique_ptr<Coordinator> c_;
};

TEST_F(StoreV013, JobsSpecsAndBandsAreAsTheOldReleaseLeftThem) {
  const std::vector<JobInfo> jobs = c_->jobs();
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs[0].job_id, kFinished);
  EXPECT_EQ(jobs[1].job_id, kUnfinished);

  const JobInfo a = *c_->job(kFinished);
  EXPECT_EQ(a.state, JobState::kSucceeded);
  EXPECT_EQ(a.spec.kind, JobKind::kRender);
  EXPECT_EQ(a.spec.scene_hash, kSpheresHash);
  EXPECT_EQ(a.spec.scene_name, "/work/main/scenes/simple/spheres.json");
  EXPECT_EQ(a.spec.width, 32);
  EXPECT_EQ(a.spec.height, 24);
  EXPECT_EQ(a.spec.frame_first, 1);
  EXPECT_EQ(a.spec.frame_last, 2);
  EXPECT_EQ(a.spec.bands, 2);
  EXPECT_EQ(a.spec.band_edges, (std::vector<int>{0, 12, 24}));
  EXPECT_EQ(a.spec.output, "shot_####.png");
  EXPECT_EQ(a.spec.orbit_degrees, 30.0);
  EXPECT_EQ(a.spec.render.method, "local");
  EXPECT_EQ(a.spec.render.boxes, "eye+shadow");
  EXPECT_EQ(a.spec.render.spp, 1);
  EXPECT_EQ(a.spec.render.aa, 4);
  EXPECT_EQ(a.spec.render.tess_tol, 0.25);
  EXPECT_EQ(a.spec.priority, 50);
  EXPECT_EQ(a.spec.frame_order, FrameOrder::kInOrder);
  EXPECT_EQ(a.spec.owner, "");
  EXPECT_TRUE(a.spec.after.empty());
  EXPECT_TRUE(a.spec.movie.empty());
  EXPECT_EQ(a.spec.row_costs.size(), 24u);
  EXPECT_EQ(a.bands_done, 4);
  EXPECT_EQ(a.frames_done, 2);
  EXPECT_EQ(a.frames_written, (std::vector<int>{1, 2}));
  EXPECT_EQ(a.stats.pixels_total, 2u * 32 * 24);
  EXPECT_EQ(a.error, "");

  const JobInfo b = *c_->job(kUnfinished);
  EXPECT_EQ(b.state, JobState::kRunning);
  EXPECT_EQ(b.spec.scene_hash, kGlassHash);
  EXPECT_EQ(b.spec.scene_name, "/work/main/scenes/anim/glass_and_mirror.json");
  EXPECT_EQ(b.spec.width, 40);
  EXPECT_EQ(b.spec.height, 30);
  EXPECT_EQ(b.spec.frame_first, 1);
  EXPECT_EQ(b.spec.frame_last, 2);
  EXPECT_EQ(b.spec.bands, 3);
  EXPECT_EQ(b.spec.band_edges, (std::vector<int>{0, 14, 17, 30}));
  EXPECT_EQ(b.spec.output, "anim_####.exr");
  EXPECT_EQ(b.spec.orbit_degrees, 0.0);
  EXPECT_EQ(b.spec.render.aa, 2);
  EXPECT_EQ(b.spec.priority, 60);
  EXPECT_EQ(b.bands_done, 4);
  EXPECT_EQ(b.frames_done, 1);
  EXPECT_EQ(b.frames_written, (std::vector<int>{1}));
  EXPECT_EQ(b.stats.pixels_total, 40u * 30 + 40u * 14);  // frame 1, band 0 of frame 2
  EXPECT_EQ(b.bands_running, 0);

  // Frame 2's band map: band 0 accepted from slow:2, band 1's lease left
  // open by the stop and voided at this start, band 2 never leased.
  auto frame = c_->frame_detail(kUnfinished, 2);
  ASSERT_TRUE(frame.ok()) << frame.status().message();
  EXPECT_FALSE(frame->written);
  ASSERT_EQ(frame->bands.size(), 3u);
  EXPECT_EQ(frame->bands[0].state, "done");
  EXPECT_EQ(frame->bands[0].worker_name, "slow:2");
  EXPECT_EQ(frame->bands[0].y0, 0);
  EXPECT_EQ(frame->bands[0].y1, 14);
  EXPECT_EQ(frame->bands[1].state, "queued");
  ASSERT_EQ(frame->bands[1].attempts.size(), 1u);
  EXPECT_EQ(frame->bands[1].attempts[0].lease_id, "3443192f-9");
  EXPECT_EQ(frame->bands[1].attempts[0].outcome, "void");
  EXPECT_EQ(frame->bands[2].state, "queued");
  EXPECT_TRUE(frame->bands[2].attempts.empty());
}

TEST_F(StoreV013, HistoryIsKeptLineByLine) {
  const std::vector<std::string> finished = {
      "submitted: /work/main/scenes/simple/spheres.json at 32x24, frames 1-2, 2 bands per frame, "
      "priority 50",
      "state running",
      "lease 3443192f-1: band 0 of frame 1 to worker w0001 (fast:1), attempt 1",
      "lease 3443192f-1 done: band 0 of frame 1 by worker w0001 in 0.009 s",
      "lease 3443192f-2: band 1 of frame 1 to worker w0001 (fast:1), attempt 1",
      "lease 3443192f-2 done: band 1 of frame 1 by worker w0001 in 0.003 s",
      "lease 3443192f-3: band 0 of frame 2 to worker w0001 (fast:1), attempt 1",
      "lease 3443192f-3 done: band 0 of frame 2 by worker w0001 in 0.002 s",
      "frame 1 written: shot_0001.png",
      "lease 3443192f-4: band 1 of frame 2 to worker w0001 (fast:1), attempt 1",
      "lease 3443192f-4 done: band 1 of frame 2 by worker w0001 in 0.002 s",
      "frame 2 written: shot_0002.png",
      "state succeeded",
      "accounting: 0.016 band-seconds rendered, 0.000 failed, 0.000 lost; 0.004 CPU seconds",
  };
  EXPECT_EQ(history(*c_, kFinished), finished);
  const std::vector<std::string> unfinished = {
      "submitted: /work/main/scenes/anim/glass_and_mirror.json at 40x30, frames 1-2, 3 bands per "
      "frame, priority 60",
      "state running",
      "lease 3443192f-5: band 0 of frame 1 to worker w0002 (slow:2), attempt 1",
      "lease 3443192f-5 done: band 0 of frame 1 by worker w0002 in 0.507 s",
      "lease 3443192f-6: band 1 of frame 1 to worker w0002 (slow:2), attempt 1",
      "lease 3443192f-6 done: band 1 of frame 1 by worker w0002 in 0.504 s",
      "lease 3443192f-7: band 2 of frame 1 to worker w0002 (slow:2), attempt 1",
      "lease 3443192f-7 done: band 2 of frame 1 by worker w0002 in 0.506 s",
      "lease 3443192f-8: band 0 of frame 2 to worker w0002 (slow:2), attempt 1",
      "frame 1 written: anim_0001.exr",
      "lease 3443192f-8 done: band 0 of frame 2 by worker w0002 in 0.509 s",
      "lease 3443192f-9: band 1 of frame 2 to worker w0002 (slow:2), attempt 1",
      // What this start adds: the lease the stop left open, voided.
      "lease 3443192f-9 void: the coordinator restarted; band back in the queue",
  };
  EXPECT_EQ(history(*c_, kUnfinished), unfinished);
}

TEST_F(StoreV013, TheFinishedJobsFramesAreFetchedAsWritten) {
  std::map<std::string, std::string> fetched;
  const Status st = c_->fetch(kFinished, Caller::anyone(), {}, [&](const FileChunk& chunk) {
    EXPECT_EQ(chunk.offset, static_cast<int64_t>(fetched[chunk.file_name].size()));
    fetched[chunk.file_name] += chunk.data;
    return true;
  });
  ASSERT_TRUE(st.ok()) << st.message();
  ASSERT_EQ(fetched.size(), 2u);
  const JobSpec spec = c_->job(kFinished)->spec;
  const v1::Scene scene = stored_scene(kSpheresHash);
  for (int f : {1, 2}) {
    const std::string name = frame_path(spec.output, f);
    SCOPED_TRACE(name);
    ASSERT_TRUE(fetched.count(name));
    EXPECT_EQ(fetched[name], file_bytes(kStore / "jobs" / kFinished / name));
    // ... and they are the image this release renders.
    const fs::path got = dir_.path / ("got_" + name);
    std::ofstream(got, std::ios::binary) << fetched[name];
    const Image ref = as_written(single_process_frame(scene, spec, f), dir_.path / ("ref_" + name));
    EXPECT_EQ(read_image(got.string())->rgb, ref.rgb);
  }
}

TEST_F(StoreV013, TheUnfinishedJobCompletesWithFramesIdenticalToOneProcess) {
  TestWorker w(*c_, "new:1");
  EXPECT_EQ(w.id, "w0003");  // worker numbers go on after the old release's
  // Its scene, as this release reads it from the old store.
  auto held = c_->get_scene(w.id, kGlassHash);
  ASSERT_TRUE(held.ok()) << held.status().message();
  const v1::Scene scene = stored_scene(kGlassHash);
  EXPECT_EQ(**held, scene.SerializeAsString());

  // Exactly the two bands the old release did not accept are leased, with
  // lease ids of this run.
  std::set<std::pair<int, int>> leased;
  while (auto t = w.take()) {
    EXPECT_EQ(t->job_id, kUnfinished);
    EXPECT_EQ(t->lease_id.rfind("3443192f-", 0), std::string::npos) << t->lease_id;
    EXPECT_TRUE(leased.insert({t->frame, t->band}).second);
    ASSERT_TRUE(w.complete(*t));
  }
  EXPECT_EQ(leased, (std::set<std::pair<int, int>>{{2, 1}, {2, 2}}));
  const JobInfo end = wait_for_end(*c_, kUnfinished);
  ASSERT_EQ(end.state, JobState::kSucceeded) << end.error;
  EXPECT_EQ(end.bands_done, 6);
  EXPECT_EQ(end.frames_written, (std::vector<int>{1, 2}));
  EXPECT_EQ(end.stats.pixels_total, 2u * 40 * 30);
  // Frame 1 as the old release wrote it, frame 2 stitched from its band
  // file and two bands of this run: both equal to one process, to the bit.
  for (int f : {1, 2}) {
    SCOPED_TRACE("frame " + std::to_string(f));
    auto got = read_image((fs::path(c_->job_dir(kUnfinished)) / frame_path(end.spec.output, f)).string());
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->rgb, single_process_frame(scene, end.spec, f).rgb);
  }
  EXPECT_EQ(file_bytes(fs::path(c_->job_dir(kUnfinished)) / "anim_0001.exr"),
            file_bytes(kStore / "jobs" / kUnfinished / "anim_0001.exr"));
  c_->shutdown();
  // Each band accepted once, across the two releases.
  auto store = JobStore::open((dir_.path / "data" / "locus.db").string());
  ASSERT_TRUE(store.ok()) << store.status().message();
  for (int f : {1, 2}) {
    for (int b = 0; b < 3; ++b) {
      EXPECT_EQ(*(*store)->band_completions(kUnfinished, f, b), 1) << "frame " << f << " band " << b;
    }
  }
}

}  // namespace
}  // namespace locus::farm
