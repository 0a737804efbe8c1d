// The farm operators' actions end to end over loopback gRPC (issue #23):
// a hung band taken back by the band timeout while its worker heartbeats,
// and the worker that cannot stop it exiting; pause and resume; a higher
// priority served first; every step in the job's history (`locus events`).
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <iterator>

#include "tests/farm_fixture.h"

namespace locus::farm::testing_farm {
namespace {

// Lines of the job's history containing `text`.
int count_events(FarmClient& client, const std::string& job, const std::string& text) {
  auto events = client.events(job, 0);
  EXPECT_TRUE(events.ok()) << events.status().message();
  int n = 0;
  for (const HistoryEntry& e : events.ok() ? *events : std::vector<HistoryEntry>{}) {
    n += e.text.find(text) != std::string::npos;
  }
  return n;
}

struct ClearRowHook {
  ~ClearRowHook() { set_row_hook_for_test({}); }
};

// One worker's single band, slowed by a row hook: submitted, then waited
// for until its render has begun (`rendering`), and then to its end.
class OneBandTest : public FarmTest {
 protected:
  std::string submit_until_rendering(const SubmitRequest& r, const std::atomic<bool>& rendering) {
    auto job = client_->submit(r);
    EXPECT_TRUE(job.ok()) << job.status().message();
    if (!job.ok()) return "";
    for (int i = 0; i < 1000 && !rendering.load(); ++i) std::this_thread::sleep_for(Millis(5));
    EXPECT_TRUE(rendering.load());
    return job->job_id;
  }
  JobInfo until_ended(const std::string& job) {
    JobInfo now;
    for (int i = 0; i < 400; ++i) {
      now = *client_->job(job);
      if (is_terminal(now.state)) break;
      std::this_thread::sleep_for(Millis(25));
    }
    return now;
  }
  // The slowed job: 16 x 24, one band, ray traced (no cost preview at
  // submit, which would meet the row hook).
  static SubmitRequest slowed(const char* output) {
    SubmitRequest r = request(kSpheres, 16, 24, 1, 1, 1, output);
    r.render.method = "raytrace";
    return r;
  }
};

TEST_F(FarmTest, AHungBandIsTakenBackAndTheWorkerThatCannotStopItExits) {
  options_.band_timeout = Millis(1000);
  start(Millis(2000));  // heartbeats every 500 ms keep the hung lease alive
  // The first row rendered hangs, deaf to the cancellation, until the
  // worker gives up on it (a wedged library call inside render_band).
  std::atomic<bool> hung{false}, release{false}, left{false};
  std::atomic<int> wedged{0};
  set_row_hook_for_test([&](int) {
    if (hung.exchange(true)) return;
    for (int i = 0; i < 3000 && !release.load(); ++i) std::this_thread::sleep_for(Millis(10));
    left = true;
  });
  ClearRowHook clear;
  // Whatever fails below, the hung render leaves the hook before the
  // hook and the flags it reads go away.
  struct Release {
    std::atomic<bool>& release;
    std::atomic<bool>& left;
    ~Release() {
      release = true;
      for (int i = 0; i < 3000 && !left.load(); ++i) std::this_thread::sleep_for(Millis(10));
    }
  } release_at_end{release, left};
  add_workers(2, [&](WorkerOptions& o) {
    o.abandon_grace = Millis(1000);
    o.on_wedged = [&] {
      ++wedged;
      release = true;
    };
  });
  SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 2, "hung_####.png");
  r.render.method = "raytrace";  // no cost preview at submit, which would meet the hook
  const auto t0 = SteadyClock::now();
  const JobInfo job = run(r);
  expect_identical(job, r);
  EXPECT_EQ(job.bands_timed_out, 1);
  // The band timeout took it back, not its lease (the worker heartbeats).
  EXPECT_EQ(count_events(*client_, job.job_id, "timed out: band hung"), 1);
  EXPECT_EQ(count_events(*client_, job.job_id, " lapsed"), 0);
  EXPECT_EQ(count_events(*client_, job.job_id, "attempt 2"), 1);
  // The hung worker gave up after its grace period, once.
  for (int i = 0; i < 1000 && wedged.load() == 0; ++i) std::this_thread::sleep_for(Millis(10));
  EXPECT_EQ(wedged.load(), 1);
  EXPECT_GE(SteadyClock::now() - t0, Millis(2000));  // timeout 1 s + heartbeat + grace 1 s
}

TEST_F(OneBandTest, AWorkerHandingBackABandMidRowIsNotTakenForWedged) {
  // The second SIGTERM (Slurm's time limit) hands the band back while a
  // row is still being rendered: the render has abandon_grace (60 s) from
  // then to return. The grace once counted from the clock's epoch, and the
  // worker exited 3 as wedged (seen as a Slurm array task FAILED 3:0).
  start(Millis(400));  // heartbeats, which check for a wedged render, every 100 ms
  std::atomic<bool> rendering{false};
  std::atomic<int> rows{0};
  std::atomic<int> wedged{0};
  set_row_hook_for_test([&](int) {
    if (rows.fetch_add(1) == 0) {
      rendering = true;
      std::this_thread::sleep_for(Millis(1000));  // one slow row, deaf to the cancellation
    }
  });
  ClearRowHook clear;
  add_workers(1, [&](WorkerOptions& o) { o.on_wedged = [&] { ++wedged; }; });
  const SubmitRequest r = slowed("handback.png");
  const std::string job = submit_until_rendering(r, rendering);
  ASSERT_FALSE(job.empty());
  workers_[0]->hand_back();
  std::this_thread::sleep_for(Millis(1300));  // the slow row's end, and heartbeats meanwhile
  EXPECT_EQ(wedged.load(), 0);
  // The band, back in the queue, is leased again and rendered.
  expect_identical(until_ended(job), r);
  EXPECT_EQ(count_events(*client_, job, "handed back"), 1);
}

TEST_F(OneBandTest, AStoppingWorkerKeepsItsLeaseAliveUntilItsBandIsReturned) {
  // SIGTERM (or `locus drain`, or Slurm's warning before a time limit)
  // mid-band: the worker finishes the band, and its heartbeats go on
  // meanwhile, so the lease does not lapse and the result is accepted.
  start(Millis(400));  // heartbeats every 100 ms; the render takes ~1.4 s
  std::atomic<bool> rendering{false};
  set_row_hook_for_test([&](int) {
    rendering = true;
    std::this_thread::sleep_for(Millis(60));
  });
  ClearRowHook clear;
  add_workers(1);
  const SubmitRequest r = slowed("drain.png");
  const std::string job = submit_until_rendering(r, rendering);
  ASSERT_FALSE(job.empty());
  workers_[0]->stop();
  // The one worker is stopping: nobody else renders it.
  expect_identical(until_ended(job), r);
  EXPECT_EQ(count_events(*client_, job, " lapsed"), 0);
  EXPECT_EQ(count_events(*client_, job, "attempt 2"), 0);
}

TEST_F(FarmTest, APausedJobLeasesNothingUntilResumedAndItsFramesAreUnchanged) {
  start();
  SubmitRequest r = request(kSpheres, 32, 24, 1, 2, 2, "paused_####.png");
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();
  auto paused = client_->pause(job->job_id);
  ASSERT_TRUE(paused.ok()) << paused.status().message();
  EXPECT_EQ(paused->state, JobState::kPaused);
  add_workers(2);
  std::this_thread::sleep_for(Millis(1500));  // three polls of each worker
  auto still = client_->job(job->job_id);
  ASSERT_TRUE(still.ok());
  EXPECT_EQ(still->state, JobState::kPaused);
  EXPECT_EQ(still->bands_done, 0);
  EXPECT_EQ(count_events(*client_, job->job_id, "lease "), 0);
  auto resumed = client_->resume(job->job_id);
  ASSERT_TRUE(resumed.ok()) << resumed.status().message();
  EXPECT_EQ(resumed->state, JobState::kQueued);
  auto done = client_->watch(job->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  expect_identical(*done, r);
  EXPECT_EQ(count_events(*client_, job->job_id, "state paused"), 1);
  EXPECT_EQ(count_events(*client_, job->job_id, "frame 2 written"), 1);
  // Wrong actions say why.
  EXPECT_EQ(client_->pause(job->job_id).status().code(), Code::kFailedPrecondition);
  EXPECT_EQ(client_->resume("j0404").status().code(), Code::kNotFound);
  EXPECT_EQ(client_->set_priority(job->job_id, 101, false).status().code(), Code::kInvalidArgument);
}

TEST_F(FarmTest, AHigherPriorityJobSubmittedLaterGetsTheWorkerFirst) {
  start();
  SubmitRequest first = request(kSpheres, 32, 24, 1, 2, 2, "low_####.png");
  auto low = client_->submit(first);
  ASSERT_TRUE(low.ok()) << low.status().message();
  SubmitRequest second = request(kSpheres, 32, 24, 1, 1, 2, "high_####.png");
  second.priority = 90;
  auto high = client_->submit(second);
  ASSERT_TRUE(high.ok()) << high.status().message();
  EXPECT_EQ(high->spec.priority, 90);
  add_workers(1);
  auto high_done = client_->watch(high->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(high_done.ok());
  expect_identical(*high_done, second);
  // The one worker rendered both of the later job's bands before any of the
  // earlier one's: their leases come first in the farm's history.
  auto low_done = client_->watch(low->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(low_done.ok());
  expect_identical(*low_done, first);
  auto h = client_->events(high->job_id, 0);
  auto l = client_->events(low->job_id, 0);
  ASSERT_TRUE(h.ok() && l.ok());
  int64_t last_high_lease = 0, first_low_lease = INT64_MAX;
  for (const HistoryEntry& e : *h) {
    if (e.text.find("lease ") == 0 && e.text.find(" to worker ") != std::string::npos)
      last_high_lease = std::max(last_high_lease, e.seq);
  }
  for (const HistoryEntry& e : *l) {
    if (e.text.find("lease ") == 0 && e.text.find(" to worker ") != std::string::npos)
      first_low_lease = std::min(first_low_lease, e.seq);
  }
  EXPECT_LT(last_high_lease, first_low_lease);
  // Accounting: the job's band-seconds and CPU seconds, in its status and
  // the last line of its history.
  EXPECT_GT(low_done->account.done, 0.0);
  EXPECT_GT(low_done->stats.seconds_render_cpu, 0.0);
  EXPECT_EQ(low_done->account.failed, 0.0);
  EXPECT_EQ(count_events(*client_, low->job_id, "accounting: "), 1);
  // A bad priority or frame order is refused at submit, naming it.
  SubmitRequest bad = request(kSpheres, 32, 24, 1, 1, 1, "bad.png");
  bad.frame_order = "random";
  auto refused = client_->submit(bad);
  EXPECT_EQ(refused.status().code(), Code::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("frame order 'random'"), std::string::npos)
      << refused.status().message();
}

// The seq of the first and last history lines of `job` containing `text`.
std::pair<int64_t, int64_t> event_span(FarmClient& client, const std::string& job,
                                       const std::string& text) {
  auto events = client.events(job, 0);
  EXPECT_TRUE(events.ok()) << events.status().message();
  std::pair<int64_t, int64_t> span{INT64_MAX, 0};
  for (const HistoryEntry& e : events.ok() ? *events : std::vector<HistoryEntry>{}) {
    if (e.text.find(text) == std::string::npos) continue;
    span.first = std::min(span.first, e.seq);
    span.second = std::max(span.second, e.seq);
  }
  return span;
}

TEST_F(FarmTest, PoolsAndDependencies) {
  start();
  SubmitRequest big = request(kSpheres, 32, 24, 1, 2, 2, "big_####.png");
  big.require = {"big"};
  auto first = client_->submit(big);
  ASSERT_TRUE(first.ok()) << first.status().message();
  SubmitRequest then = request(kSpheres, 32, 24, 1, 1, 2, "then_####.png");
  then.after = {first->job_id};
  auto second = client_->submit(then);
  ASSERT_TRUE(second.ok()) << second.status().message();
  add_workers(1);  // untagged: w0001
  std::this_thread::sleep_for(Millis(1200));
  auto waiting = client_->job(first->job_id);
  ASSERT_TRUE(waiting.ok());
  EXPECT_EQ(waiting->bands_done, 0);
  EXPECT_EQ(waiting->waiting, "waiting for a worker tagged big (none is connected)");
  EXPECT_EQ(client_->job(second->job_id)->waiting,
            "waiting for job " + first->job_id + " (queued)");
  add_workers(1, [](WorkerOptions& o) { o.tags = {"big"}; });  // w0002
  auto done = client_->watch(second->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  expect_identical(*client_->job(first->job_id), big);
  expect_identical(*done, then);
  // Only the tagged worker rendered the tagged job; the dependent job's
  // first lease came after the first job's last frame was written.
  EXPECT_EQ(count_events(*client_, first->job_id, "to worker w0001"), 0);
  EXPECT_EQ(count_events(*client_, first->job_id, "to worker w0002"), 4);
  EXPECT_LT(event_span(*client_, first->job_id, " written: ").second,
            event_span(*client_, second->job_id, " to worker ").first);
  auto ws = client_->workers();
  ASSERT_TRUE(ws.ok());
  ASSERT_EQ(ws->size(), 2u);
  EXPECT_EQ(ws->at(1).tags, std::vector<std::string>{"big"});

  // A cancelled predecessor fails its dependent, with the reason.
  SubmitRequest never = request(kSpheres, 32, 24, 1, 1, 1, "never.png");
  never.require = {"nosuchpool"};
  auto blocked = client_->submit(never);
  ASSERT_TRUE(blocked.ok());
  SubmitRequest after_blocked = request(kSpheres, 32, 24, 1, 1, 1, "after.png");
  after_blocked.after = {blocked->job_id};
  auto dependent = client_->submit(after_blocked);
  ASSERT_TRUE(dependent.ok());
  ASSERT_TRUE(client_->cancel(blocked->job_id).ok());
  auto failed = client_->job(dependent->job_id);
  ASSERT_TRUE(failed.ok());
  EXPECT_EQ(failed->state, JobState::kFailed);
  EXPECT_NE(failed->error.find(blocked->job_id), std::string::npos) << failed->error;
  EXPECT_NE(failed->error.find("cancelled"), std::string::npos) << failed->error;
  // Unknown or hopeless predecessors and bad tags are refused at submit.
  after_blocked.after = {"j0999"};
  EXPECT_EQ(client_->submit(after_blocked).status().code(), Code::kInvalidArgument);
  after_blocked.after = {blocked->job_id};
  EXPECT_NE(client_->submit(after_blocked).status().message().find("cancelled"), std::string::npos);
  SubmitRequest bad_tag = request(kSpheres, 32, 24, 1, 1, 1, "tag.png");
  bad_tag.require = {"no spaces"};
  EXPECT_NE(client_->submit(bad_tag).status().message().find("require 'no spaces'"),
            std::string::npos);
}

TEST_F(FarmTest, AnAdminDrainsAndDisablesWorkersAndOthersMayNot) {
  server_security_.auth = Authenticator::from_tokens({"ann ann-token-0123456789"}, {kWorkerToken},
                                                     {"root root-token-0123456789"});
  client_creds_.token = "ann-token-0123456789";
  start();
  Credentials rc;
  rc.token = "root-token-0123456789";
  FarmClient root(address_, rc);
  add_workers(1, [](WorkerOptions& o) { o.name = "alpha"; });
  add_workers(1, [](WorkerOptions& o) { o.name = "beta"; });
  for (int i = 0; i < 200 && client_->workers()->size() < 2; ++i)
    std::this_thread::sleep_for(Millis(10));
  auto refused = client_->drain_worker("alpha");
  EXPECT_EQ(refused.status().code(), Code::kPermissionDenied);
  EXPECT_NE(refused.status().message().find("only an admin may drain"), std::string::npos);
  EXPECT_EQ(client_->disable_worker("alpha").status().code(), Code::kPermissionDenied);
  // Disabled: alpha renders none of the job.
  ASSERT_EQ(*root.disable_worker("alpha"), "alpha");
  SubmitRequest r = request(kSpheres, 32, 24, 1, 2, 2, "disabled_####.png");
  const JobInfo job = run(r);
  expect_identical(job, r);
  EXPECT_EQ(count_events(*client_, job.job_id, "(alpha)"), 0);
  EXPECT_EQ(count_events(*client_, job.job_id, "(beta)"), 4);
  auto ws = client_->workers();
  ASSERT_TRUE(ws.ok());
  for (const WorkerInfo& w : *ws) EXPECT_EQ(w.disabled, w.name == "alpha") << w.name;
  ASSERT_TRUE(root.enable_worker("alpha").ok());
  // Drained: beta's worker process ends its run() (it would exit 0).
  ASSERT_TRUE(root.drain_worker("beta").ok());
  threads_[1].join();
  threads_[1] = std::thread([] {});
  const JobInfo after = run(request(kSpheres, 32, 24, 1, 1, 2, "after_drain_####.png"));
  EXPECT_EQ(after.state, JobState::kSucceeded);
  EXPECT_EQ(count_events(*client_, after.job_id, "(beta)"), 0);
  EXPECT_EQ(root.drain_worker("gamma").status().code(), Code::kNotFound);
}

TEST_F(FarmTest, PrivateJobsAreReadByTheirOwnerAndAdminsOnly) {
  server_security_.auth =
      Authenticator::from_tokens({"ann ann-token-0123456789", "bob bob-token-0123456789"},
                                 {kWorkerToken}, {"root root-token-0123456789"});
  client_creds_.token = "ann-token-0123456789";
  options_.private_jobs = true;
  start();
  Credentials bc, rc;
  bc.token = "bob-token-0123456789";
  rc.token = "root-token-0123456789";
  FarmClient bob(address_, bc), root(address_, rc);
  add_workers(1);
  SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 1, "private.png");
  const JobInfo job = run(r);
  expect_identical(job, r);  // the owner reads and fetches
  EXPECT_EQ(bob.job(job.job_id).status().code(), Code::kPermissionDenied);
  EXPECT_NE(bob.job(job.job_id).status().message().find("private"), std::string::npos);
  EXPECT_EQ(bob.events(job.job_id, 0).status().code(), Code::kPermissionDenied);
  EXPECT_EQ(bob.watch(job.job_id, [](const JobInfo&) {}).status().code(), Code::kPermissionDenied);
  auto fetched = bob.fetch(
      job.job_id, {}, [&](int, const std::string& n) { return (dir_ / ("bob_" + n)).string(); });
  EXPECT_EQ(fetched.status().code(), Code::kPermissionDenied);
  EXPECT_TRUE(bob.jobs()->empty());  // listed to its owner and admins only
  EXPECT_EQ(client_->jobs()->size(), 1u);
  EXPECT_EQ(root.jobs()->size(), 1u);
  EXPECT_TRUE(root.job(job.job_id).ok());
}

TEST_F(FarmTest, DeleteRemovesAFinishedJobAndRetentionOldOnes) {
  options_.retention = Millis(3000);
  options_.retention_check = Millis(100);
  start();
  SubmitRequest r = request(kSpheres, 32, 24, 1, 2, 2, "deleted_####.png");
  // Paused before any worker comes: it stays unfinished.
  auto running = client_->submit(request(kSpheres, 32, 24, 1, 1, 1, "kept.png"));
  ASSERT_TRUE(running.ok());
  ASSERT_TRUE(client_->pause(running->job_id).ok());
  add_workers(1);
  EXPECT_EQ(client_->remove(running->job_id, false).status().code(), Code::kFailedPrecondition);
  const JobInfo job = run(r);
  ASSERT_EQ(job.state, JobState::kSucceeded);
  const fs::path dir = fs::path(coordinator_->job_dir(job.job_id));
  ASSERT_TRUE(fs::exists(dir / "deleted_0002.png"));
  auto gone = client_->remove(job.job_id, false);
  ASSERT_TRUE(gone.ok()) << gone.status().message();
  EXPECT_EQ(client_->job(job.job_id).status().code(), Code::kNotFound);
  EXPECT_EQ(client_->events(job.job_id, 0).status().code(), Code::kNotFound);
  EXPECT_FALSE(fs::exists(dir / "bands"));
  EXPECT_TRUE(fs::exists(dir / "deleted_0001.png"));  // frames stay without --outputs
  // Retention: a finished job goes with its frames once old enough.
  const JobInfo old = run(request(kSpheres, 32, 24, 1, 1, 1, "old.png"));
  ASSERT_EQ(old.state, JobState::kSucceeded);
  const fs::path old_dir = fs::path(coordinator_->job_dir(old.job_id));
  EXPECT_TRUE(client_->job(old.job_id).ok());
  for (int i = 0; i < 800 && client_->job(old.job_id).ok(); ++i)
    std::this_thread::sleep_for(Millis(10));
  EXPECT_EQ(client_->job(old.job_id).status().code(), Code::kNotFound);
  EXPECT_FALSE(fs::exists(old_dir));
  EXPECT_TRUE(client_->job(running->job_id).ok());  // unfinished jobs stay
  // And the store forgets them across a restart.
  server_->shutdown(Millis(500));
  coordinator_->shutdown();
  coordinator_ = std::make_unique<Coordinator>(options_);
  ASSERT_TRUE(coordinator_->start().ok());
  EXPECT_EQ(coordinator_->job(job.job_id).status().code(), Code::kNotFound);
  EXPECT_EQ(coordinator_->jobs().size(), 1u);
}

TEST_F(FarmTest, AWarningLoggedOnTheWorkerIsInTheBandsLogAfterARestartToo) {
  start();
  // Logged inside render_band, on the row that band 1 of each frame starts
  // with (rows 12..23 of 24 in two bands).
  set_row_hook_for_test([](int row) {
    if (row == 12) spdlog::warn("test: row {} looked odd", row);
  });
  ClearRowHook clear;
  add_workers(1, [](WorkerOptions& o) { o.threads = 2; });  // from the render pool too
  SubmitRequest r = request(kSpheres, 32, 24, 1, 2, 2, "logged_####.png");
  r.render.method = "raytrace";  // no cost preview at submit, which would meet the hook
  const JobInfo job = run(r);
  ASSERT_EQ(job.state, JobState::kSucceeded);
  auto lines = client_->logs(job.job_id, -1, -1, 0);
  ASSERT_TRUE(lines.ok()) << lines.status().message();
  int odd = 0;
  for (const BandLogLine& l : *lines) {
    if (l.text.find("warning test: row 12 looked odd") == std::string::npos) continue;
    ++odd;
    EXPECT_EQ(l.band, 1);
    EXPECT_EQ(l.worker_id, "w0001");
  }
  EXPECT_EQ(odd, 2);  // one per frame
  auto frame2 = client_->logs(job.job_id, 2, 1, 0);
  ASSERT_TRUE(frame2.ok());
  ASSERT_FALSE(frame2->empty());
  for (const BandLogLine& l : *frame2) EXPECT_TRUE(l.frame == 2 && l.band == 1);
  EXPECT_TRUE(client_->logs(job.job_id, 2, 7, 0)->empty());
  server_->shutdown(Millis(500));
  coordinator_->shutdown();
  coordinator_ = std::make_unique<Coordinator>(options_);
  ASSERT_TRUE(coordinator_->start().ok());
  auto kept = coordinator_->logs(job.job_id, -1, -1, 0, 100);
  ASSERT_TRUE(kept.ok());
  EXPECT_EQ(kept->size(), lines->size());
}

TEST_F(FarmTest, OneUserCannotActOnAnothersJobButAnAdminCan) {
  server_security_.auth =
      Authenticator::from_tokens({"ann ann-token-0123456789", "bob-token-0123456789"},
                                 {kWorkerToken}, {"root root-token-0123456789"});
  client_creds_.token = "ann-token-0123456789";
  start();
  auto as = [&](const std::string& token) {
    Credentials c;
    c.token = token;
    return std::make_unique<FarmClient>(address_, c);
  };
  auto bob = as("bob-token-0123456789");  // a token alone: user token-2
  auto root = as("root-token-0123456789");
  auto job = client_->submit(request(kSpheres, 32, 24, 1, 3, 2, "owned_####.png"));
  ASSERT_TRUE(job.ok()) << job.status().message();
  EXPECT_EQ(job->spec.owner, "ann");
  for (auto code : {bob->cancel(job->job_id).status(), bob->pause(job->job_id).status(),
                    bob->set_priority(job->job_id, 90, true).status()}) {
    EXPECT_EQ(code.code(), Code::kPermissionDenied) << code.message();
    EXPECT_NE(code.message().find("belongs to ann; token-2 may not"), std::string::npos)
        << code.message();
    EXPECT_EQ(code.message().find("token-0123"), std::string::npos) << "the token leaked";
  }
  // Reading is open to every client; the owner and an admin may act.
  EXPECT_EQ(bob->job(job->job_id)->state, JobState::kQueued);
  EXPECT_TRUE(client_->pause(job->job_id).ok());
  EXPECT_TRUE(root->set_priority(job->job_id, 70, false).ok());
  auto cancelled = root->cancel(job->job_id);
  ASSERT_TRUE(cancelled.ok()) << cancelled.status().message();
  EXPECT_EQ(cancelled->state, JobState::kCancelled);
  EXPECT_EQ(count_events(*client_, job->job_id, "paused by ann"), 1);
  EXPECT_EQ(count_events(*client_, job->job_id, "priority 50 -> 70 by admin root"), 1);
  EXPECT_EQ(count_events(*client_, job->job_id, "cancelled by admin root"), 1);
  // Bob's own job is his.
  auto own = bob->submit(request(kSpheres, 32, 24, 1, 1, 1, "bobs.png"));
  ASSERT_TRUE(own.ok()) << own.status().message();
  EXPECT_EQ(own->spec.owner, "token-2");
  EXPECT_TRUE(bob->cancel(own->job_id).ok());
}

TEST_F(FarmTest, RetryAndRequeueRenderAgainAndReplaceEachFrameOnlyWhenItIsComplete) {
  start();
  SubmitRequest r = request(kSpheres, 32, 24, 1, 3, 2, "again_####.png");
  // Cancelled before any worker came; retried, it renders in full.
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();
  ASSERT_TRUE(client_->cancel(job->job_id).ok());
  auto retried = client_->retry(job->job_id);
  ASSERT_TRUE(retried.ok()) << retried.status().message();
  EXPECT_EQ(retried->state, JobState::kQueued);
  add_workers(1, [](WorkerOptions& o) { o.slow_band = Millis(150); });
  auto done = client_->watch(job->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  expect_identical(*done, r);
  EXPECT_EQ(client_->retry(job->job_id).status().code(), Code::kFailedPrecondition);
  EXPECT_EQ(client_->retry("j0404").status().code(), Code::kNotFound);
  EXPECT_EQ(client_->requeue(job->job_id, 0, 9).status().code(), Code::kInvalidArgument);

  // Frame 2 deleted, frame 3 replaced by a stand-in: requeued, each is
  // rendered again; frame 3's file is the stand-in until its new frame is
  // complete, never missing nor partial; frame 1 is left alone.
  const fs::path dir = fs::path(coordinator_->job_dir(job->job_id));
  fs::remove(dir / "again_0002.png");
  { std::ofstream(dir / "again_0003.png") << "stand-in"; }
  const auto frame1_time = fs::last_write_time(dir / "again_0001.png");
  auto requeued = client_->requeue(job->job_id, 2, std::nullopt);
  ASSERT_TRUE(requeued.ok()) << requeued.status().message();
  EXPECT_EQ(requeued->frames_written, std::vector<int>{1});
  int stand_in_seen = 0, bad = 0;
  for (;;) {
    auto now = client_->job(job->job_id);
    ASSERT_TRUE(now.ok());
    std::ifstream in(dir / "again_0003.png", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes == "stand-in") {
      ++stand_in_seen;
    } else if (!read_image((dir / "again_0003.png").string()).ok()) {
      ++bad;
    }
    if (is_terminal(now->state)) break;
    std::this_thread::sleep_for(Millis(5));
  }
  EXPECT_GT(stand_in_seen, 0);
  EXPECT_EQ(bad, 0);
  auto again = client_->job(job->job_id);
  ASSERT_TRUE(again.ok());
  expect_identical(*again, r);
  EXPECT_EQ(fs::last_write_time(dir / "again_0001.png"), frame1_time);
  EXPECT_EQ(count_events(*client_, job->job_id, "frames 2-3 requeued"), 1);
  EXPECT_EQ(count_events(*client_, job->job_id, "frame 3 written"), 2);
}

}  // namespace
}  // namespace locus::farm::testing_farm
