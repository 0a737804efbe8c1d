// The farm operators' scheduling (issue #23) on the Scheduler with a fake
// clock: priorities, fair share between users and jobs, ageing, the per-user
// cap, the first-middle-last frame order, pause and resume, preemption, the
// band timeout; and all of it through the job store and a restart.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <set>

#include "server/scheduler.h"
#include "server/store.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using test_doubles::FakeClock;
using test_doubles::pixels;
using test_doubles::TempDir;

JobSpec spec(int frames, int bands, int priority = kDefaultPriority,
             const std::string& owner = "") {
  JobSpec s = test_doubles::job_spec(4, 4, 1, frames, bands);
  s.priority = priority;
  s.owner = owner;
  return s;
}

class OperationsTest : public ::testing::Test {
 protected:
  static SchedulerOptions options() {
    SchedulerOptions o;
    o.lease = Millis(10000);
    o.worker_timeout = Millis(60000);
    o.speculate_factor = 0;
    o.ageing = Millis(0);
    return o;
  }
  OperationsTest() : s(options(), clock.fn()) {}
  explicit OperationsTest(SchedulerOptions o) : s(o, clock.fn()) {}

  std::optional<BandLease> next(const std::string& worker) {
    auto r = s.next_band(worker);
    EXPECT_TRUE(r.ok()) << r.status().message();
    return r.ok() ? *r : std::nullopt;
  }
  void done(const std::string& worker, const BandLease& t) {
    auto r = s.complete_band(pixels(worker, t));
    ASSERT_TRUE(r.ok()) << r.status().message();
    ASSERT_TRUE(r->accepted) << r->reason;
    if (r->frame) s.frame_written(t.job_id, r->frame->frame, Status::Ok());
  }

  FakeClock clock;
  Scheduler s;
};

TEST_F(OperationsTest, EqualJobsShareTheWorkersInsteadOfOneAfterTheOther) {
  const std::string j1 = s.add_job(spec(4, 1));
  const std::string j2 = s.add_job(spec(4, 1));
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1);
  // Every band takes a second on either worker: each job keeps one worker.
  std::map<std::string, std::vector<int>> finished_at;  // job -> seconds at each band
  std::optional<BandLease> ta = next(a), tb = next(b);
  ASSERT_TRUE(ta && tb);
  EXPECT_NE(ta->job_id, tb->job_id);
  for (int t = 1; ta || tb; ++t) {
    clock.advance(1000);
    for (auto [w, lease] : {std::pair{a, &ta}, std::pair{b, &tb}}) {
      if (!*lease) continue;
      done(w, **lease);
      finished_at[(*lease)->job_id].push_back(t);
      *lease = next(w);
    }
  }
  EXPECT_EQ(s.job(j1)->state, JobState::kSucceeded);
  EXPECT_EQ(s.job(j2)->state, JobState::kSucceeded);
  // Within one band-time of each other, not one after the other.
  EXPECT_LE(std::abs(finished_at[j1].back() - finished_at[j2].back()), 1);
}

TEST_F(OperationsTest, TheOlderOfTwoEqualJobsLeadsAndAHigherPriorityJobTakesTheNextWorker) {
  const std::string j1 = s.add_job(spec(4, 2));
  const std::string j2 = s.add_job(spec(4, 2));
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1), c = s.add_worker("c", 1);
  EXPECT_EQ(next(a)->job_id, j1);  // equal, none running: the older first
  EXPECT_EQ(next(b)->job_id, j2);  // j1 runs one: j2
  const std::string urgent = s.add_job(spec(1, 2, 90));
  EXPECT_EQ(next(c)->job_id, urgent);
  EXPECT_EQ(next(c)->job_id, urgent);  // both of its bands before any of the others
  EXPECT_EQ(next(c)->job_id, j1);
  EXPECT_EQ(s.job(urgent)->bands_running, 2);
}

TEST_F(OperationsTest, TwoUsersShareAFarmAlthoughOneSubmittedTenJobs) {
  std::set<std::string> many;
  for (int i = 0; i < 10; ++i) many.insert(s.add_job(spec(2, 2, kDefaultPriority, "ann")));
  const std::string one = s.add_job(spec(20, 2, kDefaultPriority, "bob"));
  const std::string w[2] = {s.add_worker("a", 1), s.add_worker("b", 1)};
  std::optional<BandLease> held[2];
  std::map<std::string, int> bands_by_user;
  for (int round = 0; round < 20; ++round) {
    for (int k = 0; k < 2; ++k) {
      if (held[k]) done(w[k], *held[k]);
      held[k] = next(w[k]);
      ASSERT_TRUE(held[k]);
      ++bands_by_user[many.count(held[k]->job_id) ? "ann" : "bob"];
    }
  }
  // One worker each, all along: 20 bands each out of 40.
  EXPECT_EQ(bands_by_user["ann"], 20);
  EXPECT_EQ(bands_by_user["bob"], 20);
  // Ann's bands are spread over her jobs (the fewest running first), and
  // her oldest jobs finish first.
  EXPECT_EQ(s.job(*many.begin())->state, JobState::kSucceeded);
}

TEST_F(OperationsTest, APerUserCapLeavesTheRestOfTheFarmToOthers) {
  SchedulerOptions o = options();
  o.user_max_running = 1;
  Scheduler capped(o, clock.fn());
  const std::string ann = capped.add_job(spec(4, 1, kDefaultPriority, "ann"));
  const std::string a = capped.add_worker("a", 1), b = capped.add_worker("b", 1);
  EXPECT_EQ((*capped.next_band(a))->job_id, ann);
  EXPECT_FALSE(capped.next_band(b)->has_value());  // ann is at her cap
  const std::string bob = capped.add_job(spec(1, 1, kDefaultPriority, "bob"));
  EXPECT_EQ((*capped.next_band(b))->job_id, bob);
}

TEST_F(OperationsTest, AgeingLetsALowPriorityJobThroughAndItNeverStarves) {
  SchedulerOptions o = options();
  o.ageing = Millis(1000);  // one point per second of waiting
  Scheduler aged(o, clock.fn());
  const std::string high = aged.add_job(spec(500, 1, 90));
  const std::string low = aged.add_job(spec(3, 1, 10));
  const std::string w = aged.add_worker("w", 1);
  // One band per second on one worker: the low job waits until its 80
  // points of difference have aged away, then gets a band, then waits again.
  std::vector<int> low_at;
  for (int t = 0; t < 200; ++t) {
    auto lease = *aged.next_band(w);
    ASSERT_TRUE(lease.has_value());
    if (lease->job_id == low) low_at.push_back(t);
    clock.advance(1000);
    ASSERT_TRUE(aged.complete_band(pixels(w, *lease))->accepted);
  }
  // At second t the low job's priority is 10 + t, the high job's 90 + 1
  // (a second since its last band): the low job passes at t = 82.
  ASSERT_EQ(low_at.size(), 2u);
  EXPECT_EQ(low_at[0], 82);
  EXPECT_EQ(low_at[1] - low_at[0], 82);
  EXPECT_EQ(aged.job(high)->bands_done, 198);
}

TEST_F(OperationsTest, FirstMiddleLastLeasesThoseFramesBeforeTheOthers) {
  JobSpec sp = spec(9, 2);
  sp.frame_first = 11;
  sp.frame_last = 19;
  sp.frame_order = FrameOrder::kFirstMiddleLast;
  s.add_job(sp);
  const std::string w = s.add_worker("w", 1);
  std::vector<int> frames;
  while (auto t = next(w)) {
    if (t->band == 0) frames.push_back(t->frame);
  }
  EXPECT_EQ(frames, (std::vector<int>{11, 15, 19, 12, 13, 14, 16, 17, 18}));
  // Two frames and one: each frame once, in that order.
  for (auto [n, expected] :
       {std::pair{2, std::vector<int>{1, 2}}, std::pair{1, std::vector<int>{1}}}) {
    JobSpec small = spec(n, 1);
    small.frame_order = FrameOrder::kFirstMiddleLast;
    s.add_job(small);
    std::vector<int> got;
    while (auto t = next(w)) got.push_back(t->frame);
    EXPECT_EQ(got, expected);
  }
}

TEST_F(OperationsTest, APausedJobTakesNoLeaseKeepsItsBandsAndFinishesAfterResume) {
  const std::string job = s.add_job(spec(2, 2));
  const std::string w = s.add_worker("w", 1);
  const BandLease in_flight = *next(w);
  ASSERT_TRUE(s.pause(job, "ann").ok());
  EXPECT_EQ(s.job(job)->state, JobState::kPaused);
  clock.advance(5000);
  EXPECT_FALSE(next(w).has_value());
  EXPECT_FALSE(s.has_queued_bands());
  done(w, in_flight);  // a band in flight finishes and is kept
  EXPECT_EQ(s.job(job)->bands_done, 1);
  EXPECT_FALSE(next(w).has_value());
  EXPECT_EQ(s.resume(job, "ann")->state, JobState::kRunning);
  EXPECT_EQ(s.resume(job).status().code(), Code::kFailedPrecondition);  // not paused
  int leased = 0;
  while (auto t = next(w)) {
    done(w, *t);
    ++leased;
  }
  EXPECT_EQ(leased, 3);
  EXPECT_EQ(s.job(job)->state, JobState::kSucceeded);
  EXPECT_EQ(s.pause(job).status().code(), Code::kFailedPrecondition);
  EXPECT_EQ(s.pause("j0099").status().code(), Code::kNotFound);
}

TEST_F(OperationsTest, PreemptingHandsLowerBandsBackWithoutChargingThem) {
  const std::string low = s.add_job(spec(1, 2, 20));
  const std::string a = s.add_worker("a", 1), b = s.add_worker("b", 1);
  const BandLease ta = *next(a), tb = *next(b);
  const std::string high = s.add_job(spec(1, 1, 20));
  // Raised without --preempt: nothing running moves.
  ASSERT_TRUE(s.set_priority(high, 80, false, "ann").ok());
  EXPECT_EQ(s.job(low)->bands_running, 2);
  ASSERT_TRUE(s.set_priority(high, 90, true, "ann").ok());
  EXPECT_EQ(s.job(low)->bands_running, 0);
  // Both workers hear it at their heartbeat; their results are dropped.
  EXPECT_EQ(*s.heartbeat(a, {ta.lease_id}), std::vector<std::string>{ta.lease_id});
  EXPECT_FALSE(s.complete_band(pixels(b, tb))->accepted);
  EXPECT_EQ(next(a)->job_id, high);
  // The handed-back bands render again, uncharged: three more attempts each.
  for (int i = 0; i < 2; ++i) {
    const BandLease t = *next(b);
    EXPECT_EQ(t.job_id, low);
    done(b, t);
  }
  EXPECT_EQ(s.job(low)->state, JobState::kSucceeded);
  EXPECT_EQ(s.set_priority(high, 101, false).status().code(), Code::kInvalidArgument);
}

TEST_F(OperationsTest, AHungBandIsTakenBackAfterTheBandTimeoutThoughItsWorkerHeartbeats) {
  SchedulerOptions o = options();
  o.lease = Millis(1000);
  o.band_timeout = Millis(5000);
  Scheduler t(o, clock.fn());
  const std::string job = t.add_job(spec(1, 1));
  JobSpec patient = spec(1, 1);
  patient.band_timeout = Millis(60000);  // its own, longer
  const std::string slow = t.add_job(patient);
  const std::string hung = t.add_worker("hung", 1), other = t.add_worker("other", 1);
  const BandLease h = **t.next_band(hung);
  const BandLease p = **t.next_band(other);
  ASSERT_EQ(h.job_id, job);
  ASSERT_EQ(p.job_id, slow);
  for (int i = 0; i < 5; ++i) {  // the heartbeat renews both leases every 0.9 s
    clock.advance(900);
    EXPECT_TRUE(t.heartbeat(hung, {h.lease_id})->empty());
    EXPECT_TRUE(t.heartbeat(other, {p.lease_id})->empty());
    t.expire();
  }
  EXPECT_EQ(t.job(job)->bands_timed_out, 0);  // 4.5 s: not yet
  clock.advance(600);                         // 5.1 s after the lease
  t.expire();
  EXPECT_EQ(*t.heartbeat(hung, {h.lease_id}), std::vector<std::string>{h.lease_id});
  EXPECT_TRUE(t.heartbeat(other, {p.lease_id})->empty());  // under its own timeout
  EXPECT_EQ(t.job(job)->bands_timed_out, 1);
  // Retried elsewhere; the hung worker's late result is dropped.
  const BandLease again = **t.next_band(other);
  EXPECT_EQ(again.job_id, job);
  EXPECT_FALSE(t.complete_band(pixels(hung, h))->accepted);
  auto r = t.complete_band(pixels(other, again));
  ASSERT_TRUE(r->accepted && r->frame);
  bool said = false;
  for (const Event& e : t.take_events()) {
    if (const auto* l = std::get_if<event::LeaseEnded>(&e)) {
      if (l->outcome == LeaseOutcome::kTimedOut) {
        said = true;
        EXPECT_EQ(l->lease_id, h.lease_id);
        EXPECT_NE(l->error.find("band hung"), std::string::npos) << l->error;
        EXPECT_NE(l->error.find("band timeout of 5.0 s"), std::string::npos) << l->error;
      }
    }
  }
  EXPECT_TRUE(said);
}

TEST_F(OperationsTest, ATaggedJobGoesOnlyToWorkersCarryingItsTagsAndSaysWhyItWaits) {
  JobSpec big = spec(1, 2);
  big.require = {"big", "gpu"};
  const std::string tagged = s.add_job(big);
  const std::string plain = s.add_worker("plain", 1);
  const std::string half = s.add_worker("half", 1, {"big"});
  EXPECT_FALSE(next(plain).has_value());
  EXPECT_FALSE(next(half).has_value());
  EXPECT_EQ(s.job(tagged)->waiting, "waiting for a worker tagged big, gpu (none is connected)");
  const std::string other = s.add_job(spec(1, 1));
  EXPECT_EQ(next(plain)->job_id, other);  // the untagged worker still serves the rest
  const std::string full = s.add_worker("full", 1, {"gpu", "big", "ssd"});
  EXPECT_EQ(s.job(tagged)->waiting, "");
  EXPECT_EQ(next(full)->job_id, tagged);
  EXPECT_EQ(next(full)->job_id, tagged);
  EXPECT_EQ(s.workers().back().tags, (std::vector<std::string>{"gpu", "big", "ssd"}));
}

TEST_F(OperationsTest, AJobAfterAnotherStartsWhenItSucceedsAndFailsWhenItIsCancelled) {
  const std::string first = s.add_job(spec(1, 2));
  JobSpec then = spec(1, 1);
  then.after = {first};
  const std::string second = s.add_job(then);
  const std::string w = s.add_worker("w", 1);
  const BandLease a = *next(w), b = *next(w);
  EXPECT_EQ(a.job_id, first);
  EXPECT_EQ(b.job_id, first);
  EXPECT_FALSE(next(w).has_value());  // the second waits, although a worker is free
  EXPECT_EQ(s.job(second)->waiting, "waiting for job " + first + " (running)");
  done(w, a);
  EXPECT_FALSE(next(w).has_value());
  done(w, b);  // the first job's last frame is written: it succeeded
  EXPECT_EQ(s.job(first)->state, JobState::kSucceeded);
  EXPECT_EQ(next(w)->job_id, second);

  const std::string doomed = s.add_job(spec(1, 1));
  JobSpec after_doomed = spec(1, 1);
  after_doomed.after = {doomed};
  const std::string dependent = s.add_job(after_doomed);
  JobSpec chain = spec(1, 1);
  chain.after = {dependent};
  const std::string last = s.add_job(chain);
  ASSERT_TRUE(s.cancel(doomed, "ann").ok());
  EXPECT_EQ(s.job(dependent)->state, JobState::kFailed);
  EXPECT_EQ(s.job(dependent)->error, "job " + doomed + ", which it waits for (--after), cancelled");
  EXPECT_EQ(s.job(last)->state, JobState::kFailed);  // and so on down the chain
  EXPECT_NE(s.job(last)->error.find(dependent), std::string::npos);
  // A new job cannot wait for a job that cannot succeed, or for none.
  EXPECT_EQ(s.check_after({doomed}).code(), Code::kInvalidArgument);
  EXPECT_NE(s.check_after({doomed}).message().find("cancelled"), std::string::npos);
  EXPECT_EQ(s.check_after({"j9999"}).code(), Code::kInvalidArgument);
  EXPECT_TRUE(s.check_after({first, second}).ok());
}

TEST_F(OperationsTest, DisabledWorkersStayOutByNameAcrossReconnectsAndRestartsDrainedOnesToo) {
  TempDir dir;
  const std::string db = (dir.path / "locus.db").string();
  const std::string job = s.add_job(spec(4, 1));
  const std::string a = s.add_worker("host:1", 1), b = s.add_worker("host:2", 1);
  ASSERT_EQ(*s.set_disabled(a, true), "host:1");  // by id: the name is kept
  EXPECT_FALSE(next(a).has_value());
  EXPECT_TRUE(s.workers()[0].disabled);
  const std::string again = s.add_worker("host:1", 1);  // it reconnects
  EXPECT_FALSE(next(again).has_value());
  EXPECT_EQ(next(b)->job_id, job);
  ASSERT_TRUE(s.drain_worker("host:2").ok());  // by name
  EXPECT_TRUE(s.draining(b));
  EXPECT_FALSE(next(b).has_value());
  EXPECT_EQ(s.drain_worker("nobody").status().code(), Code::kNotFound);
  EXPECT_EQ(s.set_disabled("nobody", true).status().code(), Code::kNotFound);
  {
    auto store = JobStore::open(db);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  auto store = JobStore::open(db);
  ASSERT_TRUE(store.ok());
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok());
  Scheduler restarted(options(), clock.fn());
  restarted.restore(*state);
  const std::string back = restarted.add_worker("host:1", 1);
  EXPECT_FALSE(restarted.next_band(back)->has_value());  // still disabled
  ASSERT_TRUE(restarted.set_disabled("host:1", false).ok());
  EXPECT_EQ((*restarted.next_band(back))->job_id, job);
  EXPECT_FALSE(restarted.workers()[0].disabled);
}

TEST_F(OperationsTest, BandSecondsAreAccountedByHowEachAttemptEnded) {
  TempDir dir;
  const std::string db = (dir.path / "locus.db").string();
  const std::string job = s.add_job(spec(1, 3, kDefaultPriority, "ann"));
  const std::string w = s.add_worker("w", 1), v = s.add_worker("v", 1);
  const BandLease ok = *next(w), bad = *next(v);
  clock.advance(2000);
  BandOutput good = pixels(w, ok);
  good.stats.seconds_render_cpu = 1.5;
  ASSERT_TRUE(s.complete_band(good)->accepted);  // 2 s done
  BandOutput failed;
  failed.worker_id = v;
  failed.lease_id = bad.lease_id;
  failed.error = "out of memory";
  ASSERT_TRUE(s.complete_band(failed).ok());  // 2 s failed
  const BandLease third = *next(w);
  clock.advance(500);
  ASSERT_TRUE(s.set_priority(s.add_job(spec(1, 1, 90)), 95, true).ok());  // 0.5 s lost
  (void)third;
  auto j = s.job(job);
  EXPECT_DOUBLE_EQ(j->account.done, 2.0);
  EXPECT_DOUBLE_EQ(j->account.failed, 2.0);
  EXPECT_DOUBLE_EQ(j->account.lost, 0.5);
  EXPECT_DOUBLE_EQ(j->stats.seconds_render_cpu, 1.5);
  {
    auto store = JobStore::open(db);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  auto store = JobStore::open(db);
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok());
  Scheduler again(options(), clock.fn());
  again.restore(*state);
  auto r = again.job(job);
  EXPECT_DOUBLE_EQ(r->account.done, 2.0);
  EXPECT_DOUBLE_EQ(r->account.failed, 2.0);
  EXPECT_DOUBLE_EQ(r->account.lost, 0.5);
  EXPECT_DOUBLE_EQ(r->stats.seconds_render_cpu, 1.5);
}

// Two bands hang at once and the first timeout fails the job (one attempt
// allowed): the second lease went with the job, and expire() goes on.
TEST_F(OperationsTest, HungBandsThatFailTheirJobEndItOnce) {
  SchedulerOptions o = options();
  o.band_timeout = Millis(1000);
  o.max_attempts = 1;
  Scheduler t(o, clock.fn());
  const std::string job = t.add_job(spec(1, 2));
  const std::string a = t.add_worker("a", 1), b = t.add_worker("b", 1);
  ASSERT_TRUE(t.next_band(a)->has_value());
  ASSERT_TRUE(t.next_band(b)->has_value());
  clock.advance(1500);
  t.expire();
  EXPECT_EQ(t.job(job)->state, JobState::kFailed);
  EXPECT_NE(t.job(job)->error.find("band hung"), std::string::npos) << t.job(job)->error;
  EXPECT_EQ(t.counts().bands_running, 0);
}

TEST_F(OperationsTest, PrioritiesPausesOrderTimeoutsAndHistorySurviveARestart) {
  TempDir dir;
  const std::string db = (dir.path / "locus.db").string();
  std::string paused, ordered;
  {
    auto store = JobStore::open(db);
    ASSERT_TRUE(store.ok()) << store.status().message();
    JobSpec sp = spec(5, 1, 70, "ann");
    sp.frame_order = FrameOrder::kFirstMiddleLast;
    sp.band_timeout = Millis(30000);
    ordered = s.add_job(sp);
    JobSpec bobs = spec(2, 1, 50, "bob");
    bobs.require = {"big"};
    bobs.after = {ordered};
    paused = s.add_job(bobs);
    const std::string w = s.add_worker("host:1", 1);
    const BandLease first = *next(w);  // frame 1
    done(w, first);
    const BandLease second = *next(w);  // frame 3, in flight at the "kill"
    EXPECT_EQ(second.frame, 3);
    ASSERT_TRUE(s.pause(paused, "bob").ok());
    ASSERT_TRUE(s.set_priority(paused, 40, false, "admin").ok());
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  auto store = JobStore::open(db);
  ASSERT_TRUE(store.ok());
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok()) << state.status().message();
  Scheduler again(options(), clock.fn());
  again.restore(*state);
  auto o = again.job(ordered);
  EXPECT_EQ(o->spec.priority, 70);
  EXPECT_EQ(o->spec.owner, "ann");
  EXPECT_EQ(o->spec.frame_order, FrameOrder::kFirstMiddleLast);
  EXPECT_EQ(o->spec.band_timeout, Millis(30000));
  auto p = again.job(paused);
  EXPECT_EQ(p->state, JobState::kPaused);
  EXPECT_EQ(p->spec.priority, 40);
  EXPECT_EQ(p->spec.require, std::vector<std::string>{"big"});
  EXPECT_EQ(p->spec.after, std::vector<std::string>{ordered});
  // The ordered job goes on in its order: frame 3 again (its lease was
  // voided), then 5, then 2 and 4; the paused job waits.
  const std::string w = again.add_worker("host:2", 1);
  std::vector<int> frames;
  while (auto t = *again.next_band(w)) {
    EXPECT_EQ(t->job_id, ordered);
    frames.push_back(t->frame);
  }
  EXPECT_EQ(frames, (std::vector<int>{3, 5, 2, 4}));
  // The history, in order, with who did what.
  auto h = (*store)->history(paused, 0, 100);
  ASSERT_TRUE(h.ok()) << h.status().message();
  std::vector<std::string> lines;
  for (const HistoryEntry& e : *h) lines.push_back(e.text);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_NE(lines[0].find("submitted by bob"), std::string::npos) << lines[0];
  EXPECT_EQ(lines[1], "state paused");
  EXPECT_EQ(lines[2], "paused by bob");
  EXPECT_EQ(lines[3], "priority 50 -> 40 by admin");
  auto ho = (*store)->history(ordered, 0, 100);
  ASSERT_TRUE(ho.ok());
  int leases = 0, done_lines = 0;
  for (const HistoryEntry& e : *ho) {
    if (e.text.find(": band 0 of frame") != std::string::npos &&
        e.text.find("attempt 1") != std::string::npos)
      ++leases;
    if (e.text.find(" done: band 0 of frame 1") != std::string::npos) ++done_lines;
  }
  EXPECT_EQ(leases, 2);
  EXPECT_EQ(done_lines, 1);
  // A cursor returns only what came after it.
  auto after = (*store)->history(ordered, ho->back().seq, 100);
  ASSERT_TRUE(after.ok());
  EXPECT_TRUE(after->empty());
}


// A worker's failure report for a leased band.
BandOutput failure(const std::string& worker, const BandLease& t, const std::string& error) {
  BandOutput o;
  o.worker_id = worker;
  o.lease_id = t.lease_id;
  o.error = error;
  return o;
}

std::vector<std::pair<int, int>> frames_and_bands(Scheduler& s, const std::string& w,
                                                  std::vector<BandLease>* leases) {
  std::vector<std::pair<int, int>> out;
  while (auto t = *s.next_band(w)) {
    out.emplace_back(t->frame, t->band);
    leases->push_back(*t);
  }
  return out;
}

TEST_F(OperationsTest, RetryGivesAFailedJobTheBandsItLacksWithFreshAttempts) {
  SchedulerOptions o = options();
  o.max_attempts = 2;
  Scheduler t(o, clock.fn());
  const std::string job = t.add_job(spec(2, 2, kDefaultPriority, "ann"));
  const std::string w = t.add_worker("w", 1), v = t.add_worker("v", 1);
  // Frame 1 is written; band 0 of frame 2 is done; band 1 of frame 2 fails
  // twice, once on each worker.
  for (int k = 0; k < 3; ++k) {
    const BandLease l = **t.next_band(w);
    auto r = t.complete_band(pixels(w, l));
    ASSERT_TRUE(r.ok() && r->accepted);
    if (r->frame) t.frame_written(job, r->frame->frame, Status::Ok());
  }
  const BandLease bad1 = **t.next_band(w);
  ASSERT_TRUE(t.complete_band(failure(w, bad1, "out of memory")).ok());
  const BandLease bad2 = **t.next_band(v);
  EXPECT_EQ(bad2.frame, 2);
  EXPECT_EQ(bad2.band, 1);
  ASSERT_TRUE(t.complete_band(failure(v, bad2, "out of memory")).ok());
  ASSERT_EQ(t.job(job)->state, JobState::kFailed);
  EXPECT_EQ(t.retry(job, "ann").status().code(), Code::kOk);
  auto j = t.job(job);
  EXPECT_EQ(j->state, JobState::kQueued);
  EXPECT_EQ(j->error, "");
  EXPECT_EQ(j->bands_done, 3);
  EXPECT_EQ(j->frames_written, std::vector<int>{1});
  // Only the band it lacks, with two fresh attempts: one more failure does
  // not fail it again.
  const BandLease again = **t.next_band(w);
  EXPECT_EQ(std::make_pair(again.frame, again.band), std::make_pair(2, 1));
  EXPECT_FALSE(t.next_band(v)->has_value());
  ASSERT_TRUE(t.complete_band(failure(w, again, "out of memory")).ok());
  EXPECT_EQ(t.job(job)->state, JobState::kRunning);
  const BandLease last = **t.next_band(v);
  auto r = t.complete_band(pixels(v, last));
  ASSERT_TRUE(r.ok() && r->accepted && r->frame);
  EXPECT_EQ(r->frame->frame, 2);
  EXPECT_TRUE(t.frame_written(job, 2, Status::Ok()));
  EXPECT_EQ(t.job(job)->state, JobState::kSucceeded);
  EXPECT_EQ(t.job(job)->frames_written, (std::vector<int>{1, 2}));
  // Only failed or cancelled jobs are retried.
  EXPECT_EQ(t.retry(job).status().code(), Code::kFailedPrecondition);
  const std::string running = t.add_job(spec(2, 1));
  ASSERT_TRUE(t.next_band(w)->has_value());
  EXPECT_EQ(t.retry(running).status().code(), Code::kFailedPrecondition);
  EXPECT_EQ(t.retry("j9999").status().code(), Code::kNotFound);
}

TEST_F(OperationsTest, ARetriedJobWritesTheFramesItFinishedBeforeItWasCancelled) {
  const std::string job = s.add_job(spec(2, 1));
  JobSpec then = spec(1, 1);
  then.after = {job};
  const std::string dependent = s.add_job(then);
  const std::string w = s.add_worker("w", 1);
  const BandLease a = *next(w);
  auto r = s.complete_band(pixels(w, a));
  ASSERT_TRUE(r->frame);  // handed to the writer, not yet written...
  ASSERT_TRUE(s.cancel(job, "ann").ok());
  EXPECT_FALSE(s.frame_written(job, 1, Status::Ok()));  // ...when the job was cancelled
  EXPECT_EQ(s.job(dependent)->state, JobState::kFailed);
  EXPECT_EQ(s.retry(dependent).status().code(), Code::kFailedPrecondition);
  EXPECT_NE(s.retry(dependent).status().message().find("retry " + job + " first"),
            std::string::npos);
  auto re = s.retry(job, "ann");
  ASSERT_TRUE(re.ok()) << re.status().message();
  ASSERT_EQ(re->ready.size(), 1u);  // frame 1's bands are done: written now
  EXPECT_EQ(re->ready[0].frame, 1);
  EXPECT_TRUE(s.frame_written(job, 1, Status::Ok()));
  EXPECT_FALSE(s.frame_written(job, 1, Status::Ok()));  // once
  EXPECT_EQ(next(w)->frame, 2);
  EXPECT_FALSE(next(w).has_value());
  // Its dependent may now be retried too.
  EXPECT_TRUE(s.retry(dependent).ok());
}

TEST_F(OperationsTest, RequeueRendersTheWrittenFramesAgainAndOnlyThose) {
  const std::string job = s.add_job(spec(4, 2, kDefaultPriority, "ann"));
  const std::string w = s.add_worker("w", 1);
  while (auto t = next(w)) done(w, *t);
  ASSERT_EQ(s.job(job)->state, JobState::kSucceeded);
  EXPECT_EQ(s.requeue(job, 0, 2).status().code(), Code::kInvalidArgument);
  EXPECT_EQ(s.requeue(job, 3, 2).status().code(), Code::kInvalidArgument);
  EXPECT_EQ(s.requeue(job, 4, 5).status().code(), Code::kInvalidArgument);
  auto r = s.requeue(job, 2, 3, "ann");
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_TRUE(r->ready.empty());
  EXPECT_EQ(r->info.state, JobState::kQueued);
  EXPECT_EQ(r->info.frames_written, (std::vector<int>{1, 4}));
  EXPECT_EQ(r->info.bands_done, 4);
  std::vector<BandLease> leases;
  EXPECT_EQ(frames_and_bands(s, w, &leases),
            (std::vector<std::pair<int, int>>{{2, 0}, {2, 1}, {3, 0}, {3, 1}}));
  for (const BandLease& l : leases) done(w, l);
  EXPECT_EQ(s.job(job)->state, JobState::kSucceeded);
  EXPECT_EQ(s.job(job)->frames_written, (std::vector<int>{1, 2, 3, 4}));
  // No bounds: every frame.
  ASSERT_TRUE(s.requeue(job, std::nullopt, std::nullopt).ok());
  leases.clear();
  EXPECT_EQ(frames_and_bands(s, w, &leases).size(), 8u);
}

TEST_F(OperationsTest, RequeueOfARunningJobPutsItsWrittenFramesFirstInItsQueue) {
  const std::string job = s.add_job(spec(3, 1));
  const std::string w = s.add_worker("w", 1);
  done(w, *next(w));  // frame 1 written
  const BandLease two = *next(w);
  EXPECT_EQ(s.requeue(job, 2, 3).status().code(), Code::kFailedPrecondition);  // none written
  auto r = s.requeue(job, 1, 2);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->info.state, JobState::kRunning);
  EXPECT_TRUE(r->info.frames_written.empty());
  EXPECT_EQ(next(w)->frame, 1);  // before frame 3
  EXPECT_EQ(next(w)->frame, 3);
  done(w, two);
  EXPECT_EQ(s.job(job)->frames_written, std::vector<int>{2});
  // Paused, it stays paused.
  ASSERT_TRUE(s.pause(job).ok());
  EXPECT_EQ(s.requeue(job, 2, 2)->info.state, JobState::kPaused);
}

TEST_F(OperationsTest, RetryAndRequeueSurviveRestartsAndEachResultIsAcceptedOnce) {
  TempDir dir;
  const std::string db = (dir.path / "locus.db").string();
  SchedulerOptions o = options();
  o.max_attempts = 1;
  std::string failed, succeeded;
  {
    Scheduler t(o, clock.fn());
    auto store = JobStore::open(db);
    ASSERT_TRUE(store.ok());
    failed = t.add_job(spec(1, 2, kDefaultPriority, "bob"));
    succeeded = t.add_job(spec(2, 1, kDefaultPriority, "ann"));
    const std::string w = t.add_worker("w", 1);
    // Equal jobs, none running: the older first. Band 0 of `failed` is
    // done, band 1 fails (one attempt allowed): the job fails. The other
    // job's first band is in flight at the kill.
    const BandLease b0 = **t.next_band(w);
    ASSERT_EQ(b0.job_id, failed);
    ASSERT_TRUE(t.complete_band(pixels(w, b0))->accepted);
    const BandLease b1 = **t.next_band(w);
    ASSERT_EQ(b1.job_id, failed);
    ASSERT_TRUE(t.complete_band(failure(w, b1, "segfault")).ok());
    ASSERT_EQ(t.job(failed)->state, JobState::kFailed);
    const BandLease lost = **t.next_band(w);
    EXPECT_EQ(lost.job_id, succeeded);
    ASSERT_TRUE((*store)->apply(t.take_events()).ok());
  }
  // First restart: the failed job is retried; the other finishes, then
  // frame 1 is requeued and its band is in flight at a second kill.
  {
    auto store = JobStore::open(db);
    auto state = (*store)->recover();
    ASSERT_TRUE(state.ok()) << state.status().message();
    Scheduler t(o, clock.fn());
    t.restore(*state);
    ASSERT_EQ(t.job(failed)->state, JobState::kFailed);
    auto re = t.retry(failed, "bob");
    ASSERT_TRUE(re.ok()) << re.status().message();
    const std::string w = t.add_worker("w2", 1);
    std::vector<BandLease> leases;
    frames_and_bands(t, w, &leases);
    // The failed band with a fresh attempt (not the band that was done),
    // and the other job's two frames.
    std::set<std::string> got;
    for (const BandLease& l : leases) {
      got.insert(l.job_id + ":" + std::to_string(l.frame) + ":" + std::to_string(l.band));
    }
    EXPECT_EQ(got,
              (std::set<std::string>{failed + ":1:1", succeeded + ":1:0", succeeded + ":2:0"}));
    for (const BandLease& l : leases) {
      auto r = t.complete_band(pixels(w, l));
      ASSERT_TRUE(r.ok() && r->accepted);
      if (r->frame) t.frame_written(l.job_id, r->frame->frame, Status::Ok());
    }
    EXPECT_EQ(t.job(failed)->state, JobState::kSucceeded);
    EXPECT_EQ(t.job(succeeded)->state, JobState::kSucceeded);
    ASSERT_TRUE(t.requeue(succeeded, 1, 1, "ann").ok());
    EXPECT_EQ((*t.next_band(w))->frame, 1);
    ASSERT_TRUE((*store)->apply(t.take_events()).ok());
  }
  auto store = JobStore::open(db);
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok());
  Scheduler t(o, clock.fn());
  t.restore(*state);
  auto j = t.job(succeeded);
  EXPECT_EQ(j->state, JobState::kRunning);
  EXPECT_EQ(j->frames_written.size(), 1u);
  const int kept = j->frames_written.at(0);
  const std::string w = t.add_worker("w3", 1);
  const BandLease l = **t.next_band(w);
  EXPECT_EQ(std::make_pair(l.job_id, l.frame), std::make_pair(succeeded, 1));
  EXPECT_FALSE(t.next_band(w)->has_value());
  auto r = t.complete_band(pixels(w, l));
  ASSERT_TRUE(r.ok() && r->accepted && r->frame);
  t.frame_written(succeeded, 1, Status::Ok());
  EXPECT_EQ(t.job(succeeded)->state, JobState::kSucceeded);
  ASSERT_TRUE(store.ok());
  ASSERT_TRUE((*store)->apply(t.take_events()).ok());
  // Each band's result was accepted once since it was last queued.
  EXPECT_EQ(*(*store)->band_completions(succeeded, 1, 0), 1);
  EXPECT_EQ(*(*store)->band_completions(succeeded, kept, 0), 1);
  EXPECT_EQ(*(*store)->band_completions(failed, 1, 0), 1);
  EXPECT_EQ(*(*store)->band_completions(failed, 1, 1), 1);
  // The history says who did what.
  auto h = (*store)->history(failed, 0, 100);
  ASSERT_TRUE(h.ok());
  bool retried = false;
  for (const HistoryEntry& e : *h) {
    retried |= e.text == "retried by bob: 1 bands back in the queue with fresh attempts";
  }
  EXPECT_TRUE(retried);
}

}  // namespace
}  // namespace locus::farm
