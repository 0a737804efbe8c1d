// The coordinator's scheduling logic without a network: a fake clock drives
// leases, hand-made band outputs play the workers.
#include "server/scheduler.h"

#include <gtest/gtest.h>

#include <optional>
#include <set>
#include <tuple>

#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {

using test_doubles::FakeClock;

JobSpec spec(int w, int h, int first, int last, int bands) {
  return test_doubles::job_spec(w, h, first, last, bands);
}

// The value a test worker writes into pixel (x, y) of frame f.
float value(int f, int x, int y, int c) {
  return static_cast<float>(f * 1000000 + y * 1000 + x * 3 + c);
}

BandOutput render(const std::string& worker, const BandLease& t) {
  BandOutput o;
  o.worker_id = worker;
  o.lease_id = t.lease_id;
  for (int y = t.y0; y < t.y1; ++y) {
    for (int x = 0; x < t.width; ++x) {
      for (int c = 0; c < 3; ++c) o.rgb.push_back(value(t.frame, x, y, c));
    }
  }
  o.stats.pixels_total = static_cast<uint64_t>(t.width) * (t.y1 - t.y0);
  return o;
}

class SchedulerTest : public ::testing::Test {
 protected:
  SchedulerTest() : s(SchedulerOptions{Millis(1000), Millis(3000), 3}, clock.fn()) {}

  BandLease lease(const std::string& worker) {
    auto r = s.next_band(worker);
    EXPECT_TRUE(r.ok()) << r.status().message();
    EXPECT_TRUE(r.ok() && r->has_value());
    return **r;
  }

  FakeClock clock;
  Scheduler s;
};

TEST(BandRows, CoverEveryRowOnce) {
  for (int h : {1, 2, 7, 48, 97}) {
    for (int n = 1; n <= h; ++n) {
      int next = 0;
      for (int i = 0; i < n; ++i) {
        const Band b = band_rows(h, n, i);
        EXPECT_EQ(b.y0, next);
        EXPECT_GT(b.y1, b.y0) << "h=" << h << " n=" << n << " i=" << i;
        next = b.y1;
      }
      EXPECT_EQ(next, h);
    }
  }
}

TEST(DefaultBands, SeveralPerWorkerWithinLimits) {
  EXPECT_EQ(default_bands(640, 480, 1, 2), 32);
  EXPECT_EQ(default_bands(640, 480, 1, 4), 64);
  EXPECT_EQ(default_bands(640, 480, 10, 2), 4);
  EXPECT_EQ(default_bands(640, 480, 100, 2), 1);  // the frames keep the workers busy
  EXPECT_EQ(default_bands(64, 3, 1, 8), 3);       // never more than the rows
  EXPECT_GE(default_bands(16384, 16384, 1, 1), min_bands(16384, 16384));
  EXPECT_GT(min_bands(16384, 16384), 1);
  // With cost counts (a job with cost maps) a band carries 21 bytes a pixel
  // more, in case they do not compress: more bands, each still in a message.
  EXPECT_GT(min_bands(16384, 16384, true), min_bands(16384, 16384));
  const int n = min_bands(16384, 16384, true);
  const int64_t rows = (16384 + n - 1) / n;  // the tallest of n bands
  EXPECT_LE(rows * 16384 * (12 + kCostCountBytes), kMaxMessageBytes - (1 << 20));
  EXPECT_GE(default_bands(16384, 16384, 1, 1, true), min_bands(16384, 16384, true));
}

TEST_F(SchedulerTest, FramesAreReadyWhenTheirLastBandIsIn) {
  const std::string job = s.add_job(spec(5, 7, 3, 4, 3));
  const std::string w1 = s.add_worker("a", 1), w2 = s.add_worker("b", 1);
  std::vector<BandLease> leases;
  for (int i = 0; i < 6; ++i) leases.push_back(lease(i % 2 ? w2 : w1));
  EXPECT_FALSE(s.next_band(w1)->has_value());
  EXPECT_EQ(s.job(job)->state, JobState::kRunning);
  std::vector<FrameReady> frames;
  for (int i : {5, 0, 3, 1, 4, 2}) {
    auto r = s.complete_band(render(i % 2 ? w2 : w1, leases[i]));
    ASSERT_TRUE(r.ok()) << r.status().message();
    EXPECT_TRUE(r->accepted) << r->reason;
    if (r->frame) frames.push_back(*r->frame);
  }
  // Frame 4 (leases 3-5) is complete with lease 4, the 5th returned; frame 3
  // (leases 0-2) with lease 2, the last.
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].frame, 4);
  EXPECT_EQ(frames[0].file_name, "shot_0004.png");
  EXPECT_EQ(frames[1].frame, 3);
  EXPECT_EQ(frames[1].file_name, "shot_0003.png");
  EXPECT_EQ(frames[1].width, 5);
  EXPECT_EQ(frames[1].height, 7);
  EXPECT_EQ(frames[1].bands, 3);
  EXPECT_EQ(s.job(job)->bands_done, 6);
  EXPECT_EQ(s.job(job)->stats.pixels_total, 70u);
  EXPECT_EQ(s.job(job)->state, JobState::kRunning);  // until the frames are written
  s.frame_written(job, 3, Status::Ok());
  s.frame_written(job, 4, Status::Ok());
  EXPECT_EQ(s.job(job)->state, JobState::kSucceeded);
  EXPECT_EQ(s.job(job)->frames_done, 2);
}

// The lease names the encoding the job's output needs, within what the
// worker offers: exr+zip for an EXR job's band that holds a block, unless
// the coordinator is run with --no-exr-zip (SchedulerOptions::exr_zip).
TEST(SchedulerEncodings, AnExrJobsBandsAreZippedWhereTheyHoldABlock) {
  for (bool exr_zip : {true, false}) {
    SCOPED_TRACE(exr_zip);
    FakeClock clock;
    SchedulerOptions o{Millis(1000), Millis(3000), 3};
    o.exr_zip = exr_zip;
    Scheduler s(o, clock.fn());
    JobSpec j = spec(8, 40, 1, 1, 3);
    j.output = "f_####.exr";
    j.band_edges = {0, 2, 32, 40};  // band 0 holds no block; 1 holds 16-31; 2 the last, 32-39
    s.add_job(j);
    const std::string offers = s.add_worker("new", 1, {}, EncodingOffers{true, true});
    const std::string older = s.add_worker("old", 1);
    std::vector<BandEncoding> got;
    for (int b = 0; b < 3; ++b) {
      auto r = s.next_band(b == 2 ? older : offers);
      ASSERT_TRUE(r.ok() && r->has_value());
      got.push_back((*r)->encoding);
    }
    const BandEncoding zip = exr_zip ? BandEncoding::kExrZip : BandEncoding::kFloat32Zstd;
    EXPECT_EQ(got, (std::vector<BandEncoding>{BandEncoding::kFloat32Zstd, zip,
                                              BandEncoding::kFloat32Zstd}));
  }
}

TEST_F(SchedulerTest, LapsedLeaseIsLeasedAgainAndItsLateResultIgnored) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 1));
  const std::string slow = s.add_worker("slow", 1), fast = s.add_worker("fast", 1);
  const BandLease first = lease(slow);
  clock.advance(1001);
  s.touch(slow);  // alive, but the lease was not renewed
  s.expire();
  const BandLease second = lease(fast);
  EXPECT_NE(first.lease_id, second.lease_id);
  EXPECT_EQ(first.band, second.band);
  auto late = s.complete_band(render(slow, first));
  ASSERT_TRUE(late.ok());
  EXPECT_FALSE(late->accepted);
  EXPECT_FALSE(late->frame);
  auto good = s.complete_band(render(fast, second));
  ASSERT_TRUE(good.ok());
  EXPECT_TRUE(good->accepted);
  EXPECT_TRUE(good->frame);
  EXPECT_EQ(s.job(job)->bands_done, 1);
}

TEST_F(SchedulerTest, ResultAfterDeadlineIsRejectedEvenBeforeExpiryRuns) {
  s.add_job(spec(4, 4, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  const BandLease t = lease(w);
  clock.advance(1500);
  auto r = s.complete_band(render(w, t));
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->accepted);
  EXPECT_NE(r->reason.find("lapsed"), std::string::npos) << r->reason;
  // The band is back in the queue.
  const BandLease again = lease(w);
  EXPECT_EQ(again.band, t.band);
}

TEST_F(SchedulerTest, HeartbeatRenewsLeases) {
  s.add_job(spec(4, 4, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  const BandLease t = lease(w);
  for (int i = 0; i < 10; ++i) {
    clock.advance(600);
    auto revoked = s.heartbeat(w, {t.lease_id});
    ASSERT_TRUE(revoked.ok());
    EXPECT_TRUE(revoked->empty());
    s.expire();
  }
  auto r = s.complete_band(render(w, t));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->accepted);
}

TEST_F(SchedulerTest, SilentWorkerIsDroppedAndItsBandsReleased) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 2));
  const std::string dead = s.add_worker("dead", 1), live = s.add_worker("live", 1);
  const BandLease t = lease(dead);
  clock.advance(900);
  s.heartbeat(live, {});
  s.heartbeat(dead, {t.lease_id});  // renewing, then it dies
  clock.advance(3100);
  s.heartbeat(live, {});
  s.expire();
  EXPECT_EQ(s.worker_count(), 1u);
  EXPECT_FALSE(s.touch(dead).ok());
  EXPECT_EQ(s.touch(dead).code(), Code::kNotFound);
  std::set<int> bands;
  bands.insert(lease(live).band);
  bands.insert(lease(live).band);
  EXPECT_EQ(bands, (std::set<int>{0, 1}));
  EXPECT_EQ(s.job(job)->state, JobState::kRunning);
}

TEST_F(SchedulerTest, CancelRevokesLeasesAndStopsDispatch) {
  const std::string job = s.add_job(spec(4, 8, 1, 3, 4));
  const std::string w = s.add_worker("w", 1);
  const BandLease t = lease(w);
  auto c = s.cancel(job);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->state, JobState::kCancelled);
  EXPECT_FALSE(s.next_band(w)->has_value());
  auto hb = s.heartbeat(w, {t.lease_id});
  ASSERT_TRUE(hb.ok());
  EXPECT_EQ(*hb, std::vector<std::string>{t.lease_id});
  auto r = s.complete_band(render(w, t));
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->accepted);
  EXPECT_EQ(s.job(job)->bands_done, 0);
  EXPECT_EQ(s.cancel("nope").status().code(), Code::kNotFound);
}

TEST_F(SchedulerTest, RepeatedFailuresFailTheJob) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  for (int i = 0; i < 3; ++i) {
    BandLease t = lease(w);
    BandOutput o;
    o.worker_id = w;
    o.lease_id = t.lease_id;
    o.error = "out of memory";
    ASSERT_TRUE(s.complete_band(o).ok());
  }
  auto j = s.job(job);
  EXPECT_EQ(j->state, JobState::kFailed);
  EXPECT_NE(j->error.find("out of memory"), std::string::npos) << j->error;
  EXPECT_NE(j->error.find("3 times"), std::string::npos) << j->error;
  EXPECT_FALSE(s.next_band(w)->has_value());
}

TEST_F(SchedulerTest, MalformedPixelsAreRefusedAndTheBandRequeued) {
  s.add_job(spec(4, 4, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  BandLease t = lease(w);
  BandOutput o = render(w, t);
  o.rgb.pop_back();
  auto r = s.complete_band(o);
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  EXPECT_NE(r.status().message().find("expected 48 floats"), std::string::npos)
      << r.status().message();
  BandLease again = lease(w);
  EXPECT_EQ(again.band, t.band);
}

TEST_F(SchedulerTest, UnknownWorkersAndForeignLeasesAreRefused) {
  s.add_job(spec(4, 4, 1, 1, 1));
  EXPECT_EQ(s.next_band("w9999").status().code(), Code::kNotFound);
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1);
  BandLease t = lease(a);
  auto r = s.complete_band(render(b, t));  // b sends a's lease
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->accepted);
  EXPECT_TRUE(s.complete_band(render(a, t))->accepted);
}

TEST_F(SchedulerTest, FailedWriteFailsTheJob) {
  const std::string job = s.add_job(spec(2, 2, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  auto r = s.complete_band(render(w, lease(w)));
  ASSERT_TRUE(r->frame);
  s.frame_written(job, 1, Internal("disk full"));
  EXPECT_EQ(s.job(job)->state, JobState::kFailed);
  EXPECT_NE(s.job(job)->error.find("disk full"), std::string::npos);
}

TEST_F(SchedulerTest, EqualJobsAreServedByRunningBandsThenSubmissionOrder) {
  // Fair share (docs/farm.md "Priorities and fair share"): the job with
  // fewer running bands first, the older one on a tie.
  const std::string j1 = s.add_job(spec(2, 2, 1, 1, 2));
  const std::string j2 = s.add_job(spec(2, 2, 1, 1, 2));
  const std::string w = s.add_worker("w", 1);
  EXPECT_EQ(lease(w).job_id, j1);
  EXPECT_EQ(lease(w).job_id, j2);
  EXPECT_EQ(lease(w).job_id, j1);
  ASSERT_EQ(s.jobs().size(), 2u);
  EXPECT_EQ(s.workers().size(), 1u);
  EXPECT_TRUE(s.workers()[0].busy);
}

BandOutput failure(const std::string& worker, const BandLease& t, const std::string& error) {
  BandOutput o;
  o.worker_id = worker;
  o.lease_id = t.lease_id;
  o.error = error;
  return o;
}

TEST_F(SchedulerTest, FailedBandGoesToAnotherWorkerWherePossible) {
  s.add_job(spec(4, 4, 1, 1, 2));
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1);
  const BandLease first = lease(a);
  ASSERT_TRUE(s.complete_band(failure(a, first, "no memory")).ok());
  // a is not given the band it failed on while b can take it...
  const BandLease next_a = lease(a);
  EXPECT_NE(next_a.band, first.band);
  // ...b is.
  const BandLease next_b = lease(b);
  EXPECT_EQ(next_b.band, first.band);
  EXPECT_NE(next_b.lease_id, first.lease_id);
}

TEST_F(SchedulerTest, AttemptsGoToDifferentWorkersThenTheJobFailsWithTheError) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 1));
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1), c = s.add_worker("c", 1);
  std::set<std::string> took;
  for (const std::string& w : {a, b, c}) {
    const BandLease t = lease(w);
    took.insert(w);
    ASSERT_TRUE(s.complete_band(failure(w, t, "bad scene on " + w)).ok());
  }
  EXPECT_EQ(took.size(), 3u);  // three attempts, three workers
  auto j = s.job(job);
  EXPECT_EQ(j->state, JobState::kFailed);
  EXPECT_NE(j->error.find("failed 3 times"), std::string::npos) << j->error;
  EXPECT_NE(j->error.find("bad scene on " + c), std::string::npos) << j->error;
  EXPECT_NE(j->error.find("worker " + c + " (c)"), std::string::npos) << j->error;
}

TEST_F(SchedulerTest, WorkerFailingRepeatedlyIsQuarantinedForThatJob) {
  const std::string j1 = s.add_job(spec(4, 8, 1, 1, 8));
  const std::string bad = s.add_worker("bad-host:1", 1), good = s.add_worker("good-host:2", 1);
  for (int i = 0; i < 2; ++i)
    ASSERT_TRUE(s.complete_band(failure(bad, lease(bad), "GPU lost")).ok());
  EXPECT_EQ(s.job(j1)->quarantined, std::vector<std::string>{"bad-host:1"});
  // No more bands of j1 for it while `good` can take them...
  EXPECT_FALSE(s.next_band(bad)->has_value());
  // ...but bands of another job, yes.
  const std::string j2 = s.add_job(spec(4, 4, 1, 1, 1));
  EXPECT_EQ(lease(bad).job_id, j2);
  // The failed bands were charged once each, the job goes on.
  for (int i = 0; i < 8; ++i) {
    auto r = s.complete_band(render(good, lease(good)));
    ASSERT_TRUE(r.ok() && r->accepted);
  }
  EXPECT_EQ(s.job(j1)->bands_done, 8);
}

TEST_F(SchedulerTest, QuarantineDoesNotStallAFarmOfOne) {
  const std::string job = s.add_job(spec(4, 8, 1, 1, 4));
  const std::string w = s.add_worker("only", 1);
  for (int i = 0; i < 2; ++i) ASSERT_TRUE(s.complete_band(failure(w, lease(w), "flaky")).ok());
  EXPECT_FALSE(s.job(job)->quarantined.empty());
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(s.complete_band(render(w, lease(w)))->accepted);
  EXPECT_EQ(s.job(job)->bands_done, 4);
}

TEST_F(SchedulerTest, SlowBandIsSpeculatedAndTheFirstResultWins) {
  const std::string job = s.add_job(spec(4, 8, 1, 1, 6));
  const std::string slow = s.add_worker("slow", 1), fast = s.add_worker("fast", 1);
  const BandLease stuck = lease(slow);
  for (int i = 0; i < 5; ++i) {
    const BandLease t = lease(fast);
    clock.advance(100);
    s.heartbeat(slow, {stuck.lease_id});
    ASSERT_TRUE(s.complete_band(render(fast, t))->accepted);
  }
  // Median 0.1 s; the stuck band has run 0.5 s: not yet past the minimum.
  EXPECT_FALSE(s.next_band(fast)->has_value());
  for (int i = 0; i < 6; ++i) {
    clock.advance(200);
    s.heartbeat(slow, {stuck.lease_id});
  }
  const BandLease copy = lease(fast);
  EXPECT_EQ(copy.band, stuck.band);
  EXPECT_NE(copy.lease_id, stuck.lease_id);
  EXPECT_EQ(s.job(job)->speculative_leases, 1);
  // Not a third copy.
  const std::string other = s.add_worker("other", 1);
  EXPECT_FALSE(s.next_band(other)->has_value());
  auto won = s.complete_band(render(fast, copy));
  ASSERT_TRUE(won.ok() && won->accepted);
  EXPECT_TRUE(won->frame);
  // The slow worker learns its band is gone; its late result is dropped.
  EXPECT_EQ(*s.heartbeat(slow, {stuck.lease_id}), std::vector<std::string>{stuck.lease_id});
  auto late = s.complete_band(render(slow, stuck));
  ASSERT_TRUE(late.ok());
  EXPECT_FALSE(late->accepted);
  const JobInfo j = *s.job(job);
  EXPECT_EQ(j.bands_done, 6);  // counted once
  EXPECT_EQ(j.results_discarded, 1);
}

TEST_F(SchedulerTest, OriginalMayStillWinOverItsSpeculativeCopy) {
  const std::string job = s.add_job(spec(4, 8, 1, 1, 4));
  const std::string slow = s.add_worker("slow", 1), fast = s.add_worker("fast", 1);
  const BandLease stuck = lease(slow);
  for (int i = 0; i < 3; ++i) {
    const BandLease t = lease(fast);
    clock.advance(10);
    ASSERT_TRUE(s.complete_band(render(fast, t))->accepted);
  }
  clock.advance(900);
  s.heartbeat(slow, {stuck.lease_id});
  clock.advance(200);
  const BandLease copy = lease(fast);
  ASSERT_EQ(copy.band, stuck.band);
  ASSERT_TRUE(s.complete_band(render(slow, stuck))->accepted);
  EXPECT_FALSE(s.complete_band(render(fast, copy))->accepted);
  EXPECT_EQ(s.job(job)->bands_done, 4);
  EXPECT_EQ(s.job(job)->results_discarded, 1);
}

TEST_F(SchedulerTest, HandedBackBandsAreNotChargedAnAttempt) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  for (int i = 0; i < 5; ++i) {
    BandOutput back;
    back.worker_id = w;
    back.lease_id = lease(w).lease_id;
    back.handed_back = true;
    auto r = s.complete_band(back);
    ASSERT_TRUE(r.ok());
  }
  EXPECT_EQ(s.job(job)->state, JobState::kRunning);
  EXPECT_TRUE(s.complete_band(render(w, lease(w)))->accepted);
  EXPECT_EQ(s.job(job)->bands_done, 1);
}

TEST_F(SchedulerTest, RetriedSubmissionFindsItsJob) {
  const std::string job = s.add_job(spec(4, 4, 1, 1, 1), "req-1", "fp");
  ASSERT_TRUE(s.job_for_request("req-1"));
  EXPECT_EQ(s.job_for_request("req-1")->job_id, job);
  EXPECT_EQ(s.job_for_request("req-1")->fingerprint, "fp");
  EXPECT_FALSE(s.job_for_request("req-2"));
  EXPECT_FALSE(s.job_for_request(""));
}

TEST_F(SchedulerTest, EveryDurableChangeIsAnEvent) {
  const std::string job = s.add_job(spec(2, 2, 1, 1, 1));
  const std::string w = s.add_worker("w", 1);
  const BandLease t = lease(w);
  auto r = s.complete_band(render(w, t));
  s.frame_written(job, 1, Status::Ok());
  std::vector<size_t> kinds;
  for (const Event& e : s.take_events()) kinds.push_back(e.index());
  // JobAdded, WorkerAdded, running, LeaseGranted, BandDone, FrameWritten,
  // succeeded, and the job's accounting line (a JobNote).
  EXPECT_EQ(kinds, (std::vector<size_t>{0, 6, 1, 2, 4, 5, 1, 8}));
  EXPECT_TRUE(s.take_events().empty());
}

// The bookkeeping that keeps dispatch from walking every job and every
// lease (issue #25): the unfinished jobs and the leases speculation looks
// at follow every change of state.
void expect_bookkeeping(const Scheduler& s, const std::string& step) {
  size_t unfinished = 0;
  bool queued = false;
  std::set<std::string> scenes;
  for (const JobInfo& j : s.jobs()) {
    if (is_terminal(j.state)) continue;
    ++unfinished;
    scenes.insert(j.spec.scene_hash);
    const int64_t waiting = j.spec.bands_total() - j.bands_done - j.bands_running;
    if (j.state != JobState::kPaused && waiting > 0) queued = true;
  }
  EXPECT_EQ(s.unfinished_jobs(), unfinished) << step;
  EXPECT_EQ(s.has_queued_bands(), queued) << step;
  EXPECT_EQ(s.scenes_in_use(), scenes) << step;
}

TEST_F(SchedulerTest, UnfinishedJobsFollowCancelRetryPauseRequeueAndForget) {
  JobSpec a_spec = spec(4, 4, 1, 1, 2);
  a_spec.scene_hash = "scene-a";
  const std::string a = s.add_job(a_spec);
  const std::string b = s.add_job(spec(4, 4, 1, 2, 1));
  const std::string w = s.add_worker("w", 1);
  expect_bookkeeping(s, "added");
  ASSERT_TRUE(s.pause(a).ok());
  expect_bookkeeping(s, "a paused");
  // Only b's bands are queued for a worker while a is paused.
  const BandLease t = lease(w);
  EXPECT_EQ(t.job_id, b);
  ASSERT_TRUE(s.complete_band(render(w, t))->accepted);
  ASSERT_TRUE(s.resume(a).ok());
  expect_bookkeeping(s, "a resumed");
  ASSERT_TRUE(s.cancel(a).ok());
  expect_bookkeeping(s, "a cancelled");
  EXPECT_FALSE(s.scenes_in_use().count("scene-a"));
  ASSERT_TRUE(s.retry(a).ok());
  expect_bookkeeping(s, "a retried");
  // a's two bands and b's last: a succeeds, then b once its first frame is
  // written; b is requeued.
  for (int i = 0; i < 3; ++i) {
    const BandLease u = lease(w);
    auto done = s.complete_band(render(w, u));
    ASSERT_TRUE(done.ok() && done->accepted);
    if (done->frame) s.frame_written(done->frame->job_id, done->frame->frame, Status::Ok());
    expect_bookkeeping(s, std::string("band ").append(std::to_string(i)));
  }
  EXPECT_EQ(s.job(a)->state, JobState::kSucceeded);
  s.frame_written(b, 1, Status::Ok());
  EXPECT_EQ(s.job(b)->state, JobState::kSucceeded);
  expect_bookkeeping(s, "b succeeded");
  ASSERT_TRUE(s.requeue(b, 2, 2).ok());
  expect_bookkeeping(s, "b requeued");
  EXPECT_EQ(s.job(b)->state, JobState::kQueued);
  s.forget_job(b);
  expect_bookkeeping(s, "b forgotten");
  EXPECT_EQ(s.unfinished_jobs(), 0u);
  // c fails at its attempt limit: nothing queued, nothing unfinished.
  const std::string c = s.add_job(spec(4, 4, 1, 1, 1));
  expect_bookkeeping(s, "c added");
  for (int i = 0; i < 3; ++i) {
    BandOutput failed;
    failed.worker_id = w;
    failed.lease_id = lease(w).lease_id;
    failed.error = "boom";
    ASSERT_TRUE(s.complete_band(failed).ok());
  }
  EXPECT_EQ(s.job(c)->state, JobState::kFailed);
  expect_bookkeeping(s, "c failed");
  EXPECT_FALSE(s.next_band(w)->has_value());
}

TEST_F(SchedulerTest, RestoredJobsAreDispatchedAndFinishedOnesAreNot) {
  RecoveredState state;
  for (JobState st : {JobState::kSucceeded, JobState::kRunning, JobState::kCancelled,
                      JobState::kPaused}) {
    RecoveredJob r;
    r.record.seq = static_cast<int64_t>(state.jobs.size()) + 1;
    r.record.job_id = std::string("j000").append(std::to_string(r.record.seq));
    r.record.spec = spec(4, 4, 1, 1, 2);
    r.state = st;
    if (st == JobState::kSucceeded) {
      r.bands_done = 2;
      r.frames_written = {1};
    }
    state.jobs.push_back(r);
  }
  Scheduler restored(SchedulerOptions{Millis(1000), Millis(3000), 3}, clock.fn());
  restored.restore(state);
  expect_bookkeeping(restored, "restored");
  EXPECT_EQ(restored.unfinished_jobs(), 2u);
  const std::string w = restored.add_worker("w", 1);
  std::set<std::string> leased;
  for (auto t = restored.next_band(w); t.ok() && t->has_value(); t = restored.next_band(w)) {
    leased.insert((*t)->job_id);
  }
  EXPECT_EQ(leased, std::set<std::string>{"j0002"});  // not the paused one, nor the ended
  ASSERT_TRUE(restored.retry("j0003").ok());
  expect_bookkeeping(restored, "j0003 retried");
  EXPECT_EQ((*restored.next_band(w))->job_id, "j0003");
}

// Speculation looks only at each job's oldest leases; it still picks the
// band running longest past its job's threshold, never the asking worker's
// own, never a band twice, never a paused job's.
TEST_F(SchedulerTest, SpeculationPicksTheLongestRunningBandOfAnyJob) {
  SchedulerOptions o{Millis(100000), Millis(100000), 3};
  o.speculate_min = Millis(100);
  Scheduler sp(o, clock.fn());
  std::vector<std::string> w;
  for (int i = 0; i < 30; ++i) w.push_back(sp.add_worker(std::string("w").append(std::to_string(i)), 1));
  auto take = [&](const std::string& worker) -> std::optional<BandLease> {
    auto r = sp.next_band(worker);
    EXPECT_TRUE(r.ok());
    return r.ok() ? *r : std::nullopt;
  };
  // Each job: three bands done in 10 ms (its threshold: the 100 ms
  // minimum), then every other band leased, 10 ms apart.
  const std::string a = sp.add_job(spec(4, 33, 1, 1, 33));
  for (int i = 0; i < 3; ++i) {
    const BandLease t = *take(w[0]);
    clock.advance(10);
    ASSERT_TRUE(sp.complete_band(render(w[0], t))->accepted);
  }
  std::vector<BandLease> running;
  for (int i = 0; i < 30; ++i) {
    running.push_back(*take(w[i]));
    clock.advance(10);
  }
  const std::string b = sp.add_job(spec(4, 4, 1, 1, 4));
  for (int i = 0; i < 3; ++i) {
    const BandLease t = *take(w[29]);
    ASSERT_EQ(t.job_id, b);
    clock.advance(10);
    ASSERT_TRUE(sp.complete_band(render(w[29], t))->accepted);
  }
  const BandLease b_last = *take(w[28]);
  ASSERT_FALSE(sp.has_queued_bands());
  clock.advance(500);
  // The oldest lease is w0's own: it gets a copy of the next oldest.
  auto copy = take(w[0]);
  ASSERT_TRUE(copy);
  EXPECT_EQ(std::tie(copy->job_id, copy->band), std::tie(running[1].job_id, running[1].band));
  // Another worker: the oldest, then the third (the second has its copy).
  copy = take(w[29]);
  ASSERT_TRUE(copy);
  EXPECT_EQ(std::tie(copy->job_id, copy->band), std::tie(running[0].job_id, running[0].band));
  copy = take(w[27]);
  ASSERT_TRUE(copy);
  EXPECT_EQ(copy->band, running[2].band);
  // The third band's original finishes first (its copy is discarded); the
  // next copy is of the fourth.
  ASSERT_TRUE(sp.complete_band(render(w[2], running[2]))->accepted);
  copy = take(w[26]);
  ASSERT_TRUE(copy);
  EXPECT_EQ(copy->band, running[3].band);
  // Job a paused: the next copy is of job b's band, then there is none.
  ASSERT_TRUE(sp.pause(a).ok());
  copy = take(w[25]);
  ASSERT_TRUE(copy);
  EXPECT_EQ(std::tie(copy->job_id, copy->band), std::tie(b_last.job_id, b_last.band));
  EXPECT_FALSE(take(w[24]));
  EXPECT_EQ(sp.job(a)->speculative_leases, 4);
  EXPECT_EQ(sp.job(b)->speculative_leases, 1);
}

}  // namespace
}  // namespace locus::farm
