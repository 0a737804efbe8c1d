// The job store and restarts, without a network: JobStore against the
// Scheduler's events, and whole Coordinators built on one data
// directory, the first abandoned as a kill -9 would leave it
// (crash_for_test), the second resuming its jobs.
#include "server/store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <thread>

#include "common/base/cost_map.h"
#include "common/base/image.h"
#include "common/render.h"
#include "common/scene/animation.h"
#include "common/scene/scene_io.h"
#include "server/band_files.h"
#include "server/coordinator.h"
#include "server/scheduler.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"
#include "worker/band_renderer.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using test_doubles::FakeClock;
using test_doubles::pixels;
using test_doubles::TempDir;
using test_doubles::TestWorker;
using test_doubles::wait_for_end;

const std::string kSpheres = std::string(LOCUS_SOURCE_DIR) + "/scenes/simple/spheres.json";

JobSpec spec(int w, int h, int first, int last, int bands) {
  JobSpec s = test_doubles::job_spec(w, h, first, last, bands, "shot_####.exr");
  s.render.spp = 2;
  s.render.aa = 3;
  s.render.tess_tol = 0.5;
  return s;
}

Result<std::unique_ptr<JobStore>> open_store(const fs::path& dir) {
  return JobStore::open((dir / "locus.db").string());
}

// Each lease's events are kept in its attempts row, not as history rows of
// text (issue #25 "compact history"), and read back as the lines they were,
// merged with the job's own history in order, through a cursor, and across
// a restart that voids the leases in flight.
TEST(JobStore, LeaseLinesComeFromTheAttemptsInOrder) {
  TempDir dir;
  FakeClock clock;
  std::string job, w1, w2;
  std::vector<BandLease> t;
  {
    auto store = open_store(dir.path);
    ASSERT_TRUE(store.ok()) << store.status().message();
    Scheduler s(SchedulerOptions{}, clock.fn());
    job = s.add_job(spec(4, 6, 1, 1, 3), "", "");
    w1 = s.add_worker("host:1", 1);
    w2 = s.add_worker("host:2", 1);
    t.push_back(**s.next_band(w1));
    t.push_back(**s.next_band(w2));
    t.push_back(**s.next_band(w2));
    clock.advance(250);  // the lease's time, in its "done" line
    ASSERT_TRUE(s.complete_band(pixels(w1, t[0]))->accepted);
    BandOutput failed;
    failed.worker_id = w2;
    failed.lease_id = t[1].lease_id;
    failed.error = "out of memory";
    ASSERT_TRUE(s.complete_band(failed).ok());
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
    // No history row of text per lease: only the job's own lines.
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path / "locus.db").string().c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM history WHERE text LIKE 'lease %'", -1,
                                 &st, nullptr),
              SQLITE_OK);
    ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
    EXPECT_EQ(sqlite3_column_int(st, 0), 0);
    sqlite3_finalize(st);
    sqlite3_close(db);
  }
  auto store = open_store(dir.path);
  ASSERT_TRUE(store.ok());
  ASSERT_TRUE((*store)->recover().ok());  // t[2] was in flight: void
  auto h = (*store)->history(job, 0, 100);
  ASSERT_TRUE(h.ok()) << h.status().message();
  std::vector<std::string> lines;
  for (const HistoryEntry& e : *h) lines.push_back(e.text);
  const auto lease = [&](int i) { return "lease " + t[i].lease_id; };
  const auto where = [&](int i) {
    return "band " + std::to_string(t[i].band) + " of frame " + std::to_string(t[i].frame);
  };
  ASSERT_EQ(lines.size(), 8u) << ::testing::PrintToString(lines);
  EXPECT_NE(lines[0].find("submitted"), std::string::npos) << lines[0];
  EXPECT_EQ(lines[1], "state running");
  EXPECT_EQ(lines[2], lease(0) + ": " + where(0) + " to worker " + w1 + " (host:1), attempt 1");
  EXPECT_EQ(lines[3], lease(1) + ": " + where(1) + " to worker " + w2 + " (host:2), attempt 1");
  EXPECT_EQ(lines[4], lease(2) + ": " + where(2) + " to worker " + w2 + " (host:2), attempt 1");
  EXPECT_EQ(lines[5], lease(0) + " done: " + where(0) + " by worker " + w1 + " in 0.250 s");
  EXPECT_EQ(lines[6], lease(1) + " failed: worker " + w2 +
                          " (host:2): out of memory; band back in the queue");
  EXPECT_EQ(lines[7], lease(2) + " void: the coordinator restarted; band back in the queue");
  for (size_t i = 1; i < h->size(); ++i) EXPECT_LT((*h)[i - 1].seq, (*h)[i].seq);
  EXPECT_EQ((*h)[5].frame, t[0].frame);
  EXPECT_EQ((*h)[5].band, t[0].band);
  // A cursor: what came after the 4th line, two at a time.
  auto page = (*store)->history(job, (*h)[3].seq, 2);
  ASSERT_TRUE(page.ok());
  ASSERT_EQ(page->size(), 2u);
  EXPECT_EQ((*page)[0].text, lines[4]);
  EXPECT_EQ((*page)[1].text, lines[5]);
  // New lines after the restart continue the sequence.
  auto more = (*store)->history(job, h->back().seq, 100);
  ASSERT_TRUE(more.ok());
  EXPECT_TRUE(more->empty());
}

// A lease granted with a result's answer is stored by a later
// transaction: its history line keeps the time of the grant.
TEST(JobStore, ALeaseLineIsTimedAtItsGrantNotWhenStored) {
  TempDir dir;
  FakeClock clock;
  auto store = open_store(dir.path);
  ASSERT_TRUE(store.ok()) << store.status().message();
  Scheduler s(SchedulerOptions{}, clock.fn());
  const std::string job = s.add_job(spec(4, 6, 1, 1, 3), "", "");
  const std::string w = s.add_worker("host:1", 1);
  const double before = wall_now();
  auto lease = s.next_band(w);
  ASSERT_TRUE(lease.ok() && *lease);
  const double granted = wall_now();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  auto h = (*store)->history(job, 0, 100);
  ASSERT_TRUE(h.ok()) << h.status().message();
  int leases = 0;
  for (const HistoryEntry& e : *h) {
    if (e.text.rfind("lease " + (*lease)->lease_id + ":", 0) != 0) continue;
    ++leases;
    EXPECT_GE(e.at, before);
    EXPECT_LE(e.at, granted);  // not the store's time, 0.3 s later
  }
  EXPECT_EQ(leases, 1);
}

TEST(JobStore, RecoversWhatTheSchedulerRecorded) {
  TempDir dir;
  FakeClock clock;
  std::string job, w1, w2;
  std::vector<std::string> open_leases;
  {
    auto store = open_store(dir.path);
    ASSERT_TRUE(store.ok()) << store.status().message();
    Scheduler s(SchedulerOptions{}, clock.fn());
    JobSpec sp = spec(4, 6, 2, 3, 3);
    sp.band_edges = {0, 1, 4, 6};  // cost-aware bands, not equal heights
    sp.render.aa = 16;
    job = s.add_job(sp, "request-7", "fingerprint");
    w1 = s.add_worker("host:1", 1);
    w2 = s.add_worker("host:2", 1);
    std::vector<BandLease> t;
    for (int i = 0; i < 5; ++i) t.push_back(**s.next_band(i % 2 ? w2 : w1));
    ASSERT_TRUE(s.complete_band(pixels(w1, t[0]))->accepted);
    ASSERT_TRUE(s.complete_band(pixels(w2, t[1]))->accepted);
    ASSERT_TRUE(s.complete_band(pixels(w1, t[2]))->accepted);  // frame 2 complete
    s.frame_written(job, 2, Status::Ok());
    BandOutput failed;
    failed.worker_id = w2;
    failed.lease_id = t[3].lease_id;
    failed.error = "out of memory";
    ASSERT_TRUE(s.complete_band(failed).ok());
    open_leases.push_back(t[4].lease_id);
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  auto store = open_store(dir.path);
  ASSERT_TRUE(store.ok());
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok()) << state.status().message();
  EXPECT_EQ(state->leases_voided, 1);  // t[4], in flight when the store was left
  EXPECT_EQ(state->next_worker, 3u);
  ASSERT_EQ(state->jobs.size(), 1u);
  const RecoveredJob& j = state->jobs[0];
  EXPECT_EQ(j.record.job_id, job);
  EXPECT_EQ(j.record.seq, 1);
  EXPECT_EQ(j.record.request_id, "request-7");
  EXPECT_EQ(j.record.fingerprint, "fingerprint");
  EXPECT_EQ(j.record.spec.width, 4);
  EXPECT_EQ(j.record.spec.frame_first, 2);
  EXPECT_EQ(j.record.spec.bands, 3);
  EXPECT_EQ(j.record.spec.output, "shot_####.exr");
  EXPECT_EQ(j.record.spec.render.spp, 2);
  EXPECT_EQ(j.record.spec.render.aa, 16);
  EXPECT_EQ(j.record.spec.render.tess_tol, 0.5);
  EXPECT_EQ(j.record.spec.band_edges, (std::vector<int>{0, 1, 4, 6}));
  EXPECT_EQ(j.state, JobState::kRunning);
  EXPECT_EQ(j.frames_written, std::vector<int>{2});
  EXPECT_EQ(j.done_bands.size(), 3u);
  EXPECT_EQ(j.stats.pixels_total, 3u * 8);
  EXPECT_EQ(j.stats.geometry_triangles, 100u);  // every band's frame, not their sum
  ASSERT_EQ(j.failures.size(), 1u);
  EXPECT_EQ(j.failures[0].frame, 3);
  EXPECT_EQ(j.failures[0].band, 0);
  EXPECT_EQ(j.failures[0].worker_name, "host:2");
  EXPECT_NE(j.failures[0].error.find("out of memory"), std::string::npos);
  EXPECT_EQ(*(*store)->band_completions(job, 2, 1), 1);
  EXPECT_EQ(*(*store)->band_completions(job, 3, 2), 0);

  // A scheduler rebuilt from it serves exactly the bands not done, numbers
  // the next job on, and knows the request id.
  Scheduler again(SchedulerOptions{}, clock.fn());
  EXPECT_TRUE(again.restore(*state).empty());
  EXPECT_EQ(again.job(job)->bands_done, 3);
  EXPECT_EQ(again.job_for_request("request-7")->job_id, job);
  const std::string w = again.add_worker("host:3", 1);
  EXPECT_EQ(w, "w0003");  // never a number of the previous run
  std::set<int> bands;
  const int edges[] = {0, 1, 4, 6};
  while (auto t = *again.next_band(w)) {
    EXPECT_EQ(t->frame, 3);
    EXPECT_EQ(t->y0, edges[t->band]);
    EXPECT_EQ(t->y1, edges[t->band + 1]);
    bands.insert(t->band);
  }
  EXPECT_EQ(bands, (std::set<int>{0, 1, 2}));
  EXPECT_EQ(again.add_job(spec(4, 6, 1, 1, 1)), "j0002");
}

TEST(JobStore, RefusesAnotherSchemaAndReportsAnUnwritableDirectory) {
  TempDir dir;
  {
    auto store = open_store(dir.path);
    ASSERT_TRUE(store.ok());
  }
  auto bad = JobStore::open((dir.path / "no" / "such" / "dir" / "locus.db").string());
  EXPECT_EQ(bad.status().code(), Code::kFailedPrecondition);
  EXPECT_NE(bad.status().message().find("cannot open the job store"), std::string::npos);
  std::ofstream((dir.path / "junk.db").string()) << "not a database at all, just text";
  auto junk = JobStore::open((dir.path / "junk.db").string());
  EXPECT_FALSE(junk.ok());
}

// A band's record deleted (its frame written, or the band forgotten) is not
// written again as zeros (secure_delete off; Debian's SQLite has it on):
// the WAL grows by a few pages, not by the record's size
// (docs/farm.md "The job store").
TEST(JobStore, ADeletedBandRecordIsNotWrittenAgainAsZeros) {
  TempDir dir;
  auto store = open_store(dir.path);
  ASSERT_TRUE(store.ok()) << store.status().message();
  std::string record(1 << 20, '\0');
  std::mt19937 rng(7);
  for (char& c : record) c = static_cast<char>(rng());
  ASSERT_TRUE((*store)->put_band_record("j0001", 0, 0, record).ok());
  const fs::path wal = dir.path / "locus.db-wal";
  ASSERT_TRUE(fs::exists(wal));
  const auto before = fs::file_size(wal);
  ASSERT_TRUE((*store)->forget_band("j0001", 0, 0).ok());
  EXPECT_EQ((*store)->band_record("j0001", 0, 0).status().code(), Code::kNotFound);
  const auto grown = fs::file_size(wal) - before;
  EXPECT_LT(grown, record.size() / 16) << grown << " bytes written to delete " << record.size();
}

TEST(JobStore, AStoreFromBeforeTheRenderColumnsGetsThemWithTheOldDefaults) {
  TempDir dir;
  FakeClock clock;
  {
    auto store = open_store(dir.path);
    ASSERT_TRUE(store.ok());
    Scheduler s(SchedulerOptions{}, clock.fn());
    s.add_job(spec(4, 6, 1, 1, 2));
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  {
    // The jobs table as written before `aa`, `tess_tol` and `band_edges`
    // were stored.
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path / "locus.db").string().c_str(), &db), SQLITE_OK);
    EXPECT_EQ(
        sqlite3_exec(db,
                     "ALTER TABLE jobs DROP COLUMN aa; ALTER TABLE jobs DROP COLUMN tess_tol; "
                     "ALTER TABLE jobs DROP COLUMN band_edges",
                     nullptr, nullptr, nullptr),
        SQLITE_OK)
        << sqlite3_errmsg(db);
    sqlite3_close(db);
  }
  auto store = open_store(dir.path);
  ASSERT_TRUE(store.ok()) << store.status().message();
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok()) << state.status().message();
  ASSERT_EQ(state->jobs.size(), 1u);
  EXPECT_EQ(state->jobs[0].record.spec.render.aa, -1);  // the method's default
  EXPECT_EQ(state->jobs[0].record.spec.render.tess_tol, kDefaultTessTol);
  EXPECT_TRUE(state->jobs[0].record.spec.band_edges.empty());  // equal heights
  EXPECT_EQ(band_rows(state->jobs[0].record.spec, 1).y0, 3);
}

// ---------------------------------------------------------------- restarts

SubmitRequest spheres(int first, int last, int bands, const std::string& request_id = "") {
  auto scene = load_scene(kSpheres);
  EXPECT_TRUE(scene.ok());
  SubmitRequest r;
  r.scene = scene_to_proto(*scene);
  r.scene_name = kSpheres;
  r.width = 16;
  r.height = 12;
  r.frame_first = first;
  r.frame_last = last;
  r.bands = bands;
  r.output = "out/f_####.exr";
  r.orbit_degrees = 40;
  r.request_id = request_id;
  return r;
}

// No syncs: what a kill -9 tests does not depend on them.
CoordinatorOptions options(const fs::path& dir) { return test_doubles::test_options(dir); }

// Every frame of the job equals a single-process render, to the bit.
void expect_frames_identical(Coordinator& c, const JobInfo& job, const SubmitRequest& r) {
  ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;
  ASSERT_EQ(job.frames_done, r.frame_last - r.frame_first + 1);
  auto scene = load_scene(kSpheres);
  for (int f = r.frame_first; f <= r.frame_last; ++f) {
    const Scene s =
        frame_scene(*scene, r.width, r.height, f, r.frame_first, r.frame_last, r.orbit_degrees);
    auto ref = render_image(s, *to_render_params(r.render, 1));
    ASSERT_TRUE(ref.ok());
    auto got = read_image((fs::path(c.job_dir(job.job_id)) / frame_path("f_####.exr", f)).string());
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->rgb, ref->pixels.rgb) << "frame " << f;
  }
}

void expect_each_band_once(const fs::path& dir, const JobInfo& job) {
  auto store = open_store(dir / "data");
  ASSERT_TRUE(store.ok());
  for (int f = job.spec.frame_first; f <= job.spec.frame_last; ++f) {
    for (int b = 0; b < job.spec.bands; ++b) {
      EXPECT_EQ(*(*store)->band_completions(job.job_id, f, b), 1) << "frame " << f << " band " << b;
    }
  }
}

TEST(CoordinatorRestart, ResumesWithoutRenderingABandTwiceOrLosingOne) {
  TempDir dir;
  const SubmitRequest r = spheres(1, 3, 4);
  std::string job;
  std::set<std::pair<int, int>> done_before;
  BandLease in_flight;
  BandOutput late;
  {
    Coordinator a(options(dir.path));
    ASSERT_TRUE(a.start().ok());
    auto submitted = a.submit(r);
    ASSERT_TRUE(submitted.ok()) << submitted.status().message();
    job = submitted->job_id;
    TestWorker w(a, "first:1");
    for (int i = 0; i < 6; ++i) {
      auto t = w.take();
      ASSERT_TRUE(t);
      ASSERT_TRUE(w.complete(*t));
      done_before.insert({t->frame, t->band});
    }
    in_flight = *w.take();
    late = w.render(in_flight);
    a.crash_for_test();
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  auto resumed = b.job(job);
  ASSERT_TRUE(resumed.ok()) << resumed.status().message();
  EXPECT_EQ(resumed->bands_done, 6);
  EXPECT_FALSE(is_terminal(resumed->state));
  TestWorker w(b, "second:2");
  // The result of a lease of the previous run is refused.
  late.worker_id = w.id;
  auto stale = b.complete_band(late);
  ASSERT_TRUE(stale.ok());
  EXPECT_FALSE(stale->accepted);
  std::set<std::pair<int, int>> done_after;
  while (auto t = w.take()) {
    EXPECT_FALSE(done_before.count({t->frame, t->band}))
        << "band " << t->band << " of frame " << t->frame << " rendered again";
    EXPECT_TRUE(done_after.insert({t->frame, t->band}).second);
    ASSERT_TRUE(w.complete(*t));
  }
  EXPECT_EQ(done_before.size() + done_after.size(), 12u);
  const JobInfo end = wait_for_end(b, job);
  expect_frames_identical(b, end, r);
  b.shutdown();
  expect_each_band_once(dir.path, end);
}

// A job with cost maps across a crash: the bands accepted before it keep
// their counts in their records (LOCBAND3), so the frame's map, written
// after the restart, is the picture of every band's own counts.
TEST(CoordinatorRestart, CostCountsOfBandsDoneBeforeACrashReachTheMap) {
  TempDir dir;
  SubmitRequest r = spheres(1, 1, 3);
  r.cost_map = "c_####.png";
  std::string job;
  CostBuffer counts;
  counts.reset(r.width, 0, r.height);
  const auto keep = [&](const BandLease& t, const BandOutput& out) {
    auto band = decode_band_cost(out.cost, t.width, t.y0, t.y1);
    ASSERT_TRUE(band.ok()) << band.status().message();
    std::copy(band->pixels.begin(), band->pixels.end(),
              counts.pixels.begin() + static_cast<size_t>(t.y0) * t.width);
  };
  {
    Coordinator a(options(dir.path));
    ASSERT_TRUE(a.start().ok());
    auto submitted = a.submit(r);
    ASSERT_TRUE(submitted.ok()) << submitted.status().message();
    job = submitted->job_id;
    TestWorker w(a, "first:1");
    for (int i = 0; i < 2; ++i) {
      auto t = w.take();
      ASSERT_TRUE(t && t->cost_map);
      const BandOutput out = w.render(*t);
      keep(*t, out);
      auto done = a.complete_band(out);
      ASSERT_TRUE(done.ok() && done->accepted);
    }
    a.crash_for_test();
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  TestWorker w(b, "second:2");
  auto t = w.take();
  ASSERT_TRUE(t && t->cost_map);
  const BandOutput out = w.render(*t);
  keep(*t, out);
  ASSERT_TRUE(b.complete_band(out).ok());
  const JobInfo end = wait_for_end(b, job);
  ASSERT_EQ(end.state, JobState::kSucceeded) << end.error;
  const fs::path want = dir.path / "want.png";
  ASSERT_TRUE(write_image(want.string(), cost_map_image(counts), true).ok());
  auto map = read_image(b.job_dir(job) + "/c_0001.png");
  auto expected = read_image(want.string());
  ASSERT_TRUE(map.ok() && expected.ok());
  EXPECT_EQ(map->rgb, expected->rgb);
  EXPECT_GT(counts.totals().rays_eye, 0u);
  b.shutdown();
}

TEST(CoordinatorRestart, CrashAtRandomMomentsLosesAndDuplicatesNothing) {
  for (int seed = 1; seed <= 12; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    TempDir dir;
    std::mt19937 rng(seed);
    const SubmitRequest r = spheres(2, 4, 3);
    std::string job;
    {
      Coordinator a(options(dir.path));
      ASSERT_TRUE(a.start().ok());
      job = a.submit(r)->job_id;
      TestWorker w1(a, "one:1"), w2(a, "two:2");
      std::vector<std::pair<TestWorker*, BandLease>> held;
      const int steps = static_cast<int>(rng() % 14);
      for (int i = 0; i < steps; ++i) {
        TestWorker* w = rng() % 2 ? &w1 : &w2;
        if (held.empty() || rng() % 3 == 0) {
          if (auto t = w->take()) held.push_back({w, *t});
        } else {
          const size_t k = rng() % held.size();
          auto [who, t] = held[k];
          held.erase(held.begin() + static_cast<long>(k));
          if (rng() % 5 == 0) {
            BandOutput err;
            err.worker_id = who->id;
            err.lease_id = t.lease_id;
            err.error = "injected";
            ASSERT_TRUE(a.complete_band(err).ok());
          } else {
            who->complete(t);
          }
        }
      }
      // Sometimes the writer had time for the frames, sometimes not.
      if (rng() % 2) std::this_thread::sleep_for(Millis(30));
      a.crash_for_test();
    }
    Coordinator b(options(dir.path));
    ASSERT_TRUE(b.start().ok());
    TestWorker w(b, "three:3");
    while (auto t = w.take()) ASSERT_TRUE(w.complete(*t));
    const JobInfo end = wait_for_end(b, job);
    expect_frames_identical(b, end, r);
    EXPECT_EQ(end.bands_done, 9);
    b.shutdown();
    expect_each_band_once(dir.path, end);
    // No band record outlives its written frame.
    auto store = open_store(dir.path / "data");
    ASSERT_TRUE(store.ok());
    for (int f = 1; f <= 3; ++f) {
      for (int band = 0; band < 3; ++band) {
        EXPECT_EQ((*store)->band_record(job, f, band).status().code(), Code::kNotFound);
      }
    }
  }
}

// A kill while a group commit's batch waits (issue #25 item 2): a band
// acknowledged before it is kept; a band whose batch had not been made
// durable was never acknowledged (its worker hears an error, not
// "accepted"), and whether or not the store kept it, the job ends with
// every band accepted once and frames identical.
TEST(CoordinatorRestart, AKillDuringAGroupCommitLosesNoAcknowledgedBand) {
  TempDir dir;
  const SubmitRequest r = spheres(1, 2, 3);
  std::string job;
  BandLease acked;
  {
    CoordinatorOptions o = options(dir.path);
    o.fsync = true;
    o.group_commit = Millis(300);  // a batch in flight for long enough to kill it
    Coordinator a(o);
    ASSERT_TRUE(a.start().ok());
    auto submitted = a.submit(r);
    ASSERT_TRUE(submitted.ok()) << submitted.status().message();
    job = submitted->job_id;
    TestWorker w(a, "first:1");
    auto first = w.take();
    ASSERT_TRUE(first.has_value());
    acked = *first;
    const auto before = std::chrono::steady_clock::now();
    ASSERT_TRUE(w.complete(acked));  // waits for its batch: durable once this returns
    EXPECT_GE(std::chrono::steady_clock::now() - before, Millis(250));
    EXPECT_EQ(a.log_syncs(), 1u);
    auto second = w.take();
    ASSERT_TRUE(second.has_value());
    std::mutex mu;
    std::optional<Result<CompleteOutcome>> answer;
    a.complete_band_async(w.render(*second), [&](Result<CompleteOutcome> got) {
      std::lock_guard lk(mu);
      answer = std::move(got);
    });
    {
      std::lock_guard lk(mu);
      EXPECT_FALSE(answer.has_value()) << "answered before its batch was durable";
    }
    a.crash_for_test();
    std::lock_guard lk(mu);
    ASSERT_TRUE(answer.has_value()) << "a caller left waiting by the crash";
    EXPECT_FALSE(answer->ok() && (*answer)->accepted) << "acknowledged, yet not durable";
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  auto resumed = b.job(job);
  ASSERT_TRUE(resumed.ok());
  EXPECT_GE(resumed->bands_done, 1);
  TestWorker w(b, "second:2");
  while (auto t = w.take()) {
    EXPECT_FALSE(t->frame == acked.frame && t->band == acked.band)
        << "an acknowledged band was rendered again";
    ASSERT_TRUE(w.complete(*t));
  }
  const JobInfo end = wait_for_end(b, job);
  expect_frames_identical(b, end, r);
  b.shutdown();
  expect_each_band_once(dir.path, end);
}

// A band's record damaged on disk (a flipped byte in the store) is caught
// by its checksum at the restart and the band rendered again; the frame
// comes out identical all the same.
TEST(CoordinatorRestart, ADamagedBandRecordIsRenderedAgain) {
  TempDir dir;
  const SubmitRequest r = spheres(1, 1, 3);
  std::string job;
  {
    Coordinator a(options(dir.path));
    ASSERT_TRUE(a.start().ok());
    auto submitted = a.submit(r);
    ASSERT_TRUE(submitted.ok()) << submitted.status().message();
    job = submitted->job_id;
    TestWorker w(a, "first:1");
    for (int i = 0; i < 2; ++i) {
      auto t = w.take();
      ASSERT_TRUE(t.has_value());
      ASSERT_TRUE(w.complete(*t));
    }
    a.crash_for_test();
  }
  int damaged = -1;
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open((dir.path / "data" / "locus.db").c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    ASSERT_EQ(
        sqlite3_prepare_v2(db, "SELECT band, pixels FROM band_pixels LIMIT 1", -1, &st, nullptr),
        SQLITE_OK);
    ASSERT_EQ(sqlite3_step(st), SQLITE_ROW);
    damaged = sqlite3_column_int(st, 0);
    std::string bytes(static_cast<const char*>(sqlite3_column_blob(st, 1)),
                      sqlite3_column_bytes(st, 1));
    sqlite3_finalize(st);
    bytes[bytes.size() / 2] ^= 0x55;
    ASSERT_EQ(sqlite3_prepare_v2(db, "UPDATE band_pixels SET pixels = ? WHERE band = ?", -1, &st,
                                 nullptr),
              SQLITE_OK);
    sqlite3_bind_blob(st, 1, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
    sqlite3_bind_int(st, 2, damaged);
    ASSERT_EQ(sqlite3_step(st), SQLITE_DONE);
    sqlite3_finalize(st);
    sqlite3_close(db);
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  auto resumed = b.job(job);
  ASSERT_TRUE(resumed.ok());
  EXPECT_EQ(resumed->bands_done, 1);  // the damaged one no longer counts
  TestWorker w(b, "second:2");
  std::set<int> rendered;
  while (auto t = w.take()) {
    rendered.insert(t->band);
    ASSERT_TRUE(w.complete(*t));
  }
  EXPECT_TRUE(rendered.count(damaged)) << "band " << damaged << " was not rendered again";
  const JobInfo end = wait_for_end(b, job);
  EXPECT_EQ(end.state, JobState::kSucceeded);
  expect_frames_identical(b, end, r);
}

TEST(CoordinatorRestart, ADataDirectoryServesOneCoordinatorAtATime) {
  TempDir dir;
  Coordinator a(options(dir.path));
  ASSERT_TRUE(a.start().ok());
  Coordinator b(options(dir.path));
  const Status busy = b.start();
  EXPECT_EQ(busy.code(), Code::kFailedPrecondition);
  EXPECT_NE(busy.message().find("in use by another coordinator"), std::string::npos)
      << busy.message();
  a.crash_for_test();  // a dead coordinator leaves no lock behind
  Coordinator c(options(dir.path));
  EXPECT_TRUE(c.start().ok());
}

TEST(CoordinatorRestart, ARetriedSubmissionCreatesNoSecondJobEvenAcrossARestart) {
  TempDir dir;
  std::string job;
  {
    Coordinator a(options(dir.path));
    ASSERT_TRUE(a.start().ok());
    auto first = a.submit(spheres(1, 2, 2, "token-1"));
    ASSERT_TRUE(first.ok());
    job = first->job_id;
    auto retry = a.submit(spheres(1, 2, 2, "token-1"));
    ASSERT_TRUE(retry.ok());
    EXPECT_EQ(retry->job_id, job);
    auto reused = a.submit(spheres(1, 3, 2, "token-1"));
    EXPECT_EQ(reused.status().code(), Code::kAlreadyExists);
    EXPECT_NE(reused.status().message().find(job), std::string::npos);
    EXPECT_EQ(a.submit(spheres(1, 2, 2, "bad token")).status().code(), Code::kInvalidArgument);
    EXPECT_EQ(a.jobs().size(), 1u);
    a.crash_for_test();
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  auto retry = b.submit(spheres(1, 2, 2, "token-1"));
  ASSERT_TRUE(retry.ok());
  EXPECT_EQ(retry->job_id, job);
  auto other = b.submit(spheres(1, 2, 2, "token-2"));
  ASSERT_TRUE(other.ok());
  EXPECT_EQ(other->job_id, "j0002");
  EXPECT_EQ(b.jobs().size(), 2u);
}

TEST(CoordinatorRestart, FinishedJobsStayFetchableAndCancelledStayCancelled) {
  TempDir dir;
  const SubmitRequest r = spheres(1, 1, 2);
  std::string done, cancelled;
  {
    Coordinator a(options(dir.path));
    ASSERT_TRUE(a.start().ok());
    done = a.submit(r)->job_id;
    cancelled = a.submit(spheres(1, 5, 2))->job_id;
    TestWorker w(a, "w:1");
    for (int i = 0; i < 2; ++i) ASSERT_TRUE(w.complete(*w.take()));
    wait_for_end(a, done);
    ASSERT_TRUE(a.cancel(cancelled).ok());
    a.shutdown();
  }
  Coordinator b(options(dir.path));
  ASSERT_TRUE(b.start().ok());
  const JobInfo j = *b.job(done);
  EXPECT_EQ(j.state, JobState::kSucceeded);
  EXPECT_EQ(j.frames_written, std::vector<int>{1});
  expect_frames_identical(b, j, r);
  size_t bytes = 0;
  ASSERT_TRUE(b.fetch(done, Caller::anyone(), {}, [&](const FileChunk& c) {
                 bytes += c.data.size();
                 return true;
               }).ok());
  EXPECT_GT(bytes, 0u);
  EXPECT_EQ(b.job(cancelled)->state, JobState::kCancelled);
  TestWorker w(b, "w:2");
  EXPECT_FALSE(w.take());  // nothing to do
}

}  // namespace
}  // namespace locus::farm
