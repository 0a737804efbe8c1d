// Movie jobs (issue #26 item 1) on the Scheduler with a fake clock: a job
// without bands after its render job, made by the coordinator; retried
// after back-off, failed after the attempt limit, stopped by a cancel,
// retried and requeued; and through the job store across a restart. The
// movie and notification checks of a submission (server/submission.h,
// common/farm/movie.h) too.
#include <gtest/gtest.h>

#include <filesystem>

#include "common/farm/movie.h"
#include "server/scheduler.h"
#include "server/store.h"
#include "server/submission.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
using test_doubles::FakeClock;
using test_doubles::pixels;
using test_doubles::TempDir;

class MovieJobTest : public ::testing::Test {
 protected:
  static SchedulerOptions options() {
    SchedulerOptions o;
    o.lease = Millis(10000);
    o.worker_timeout = Millis(60000);
    o.speculate_factor = 0;
    o.max_attempts = 3;
    return o;
  }
  MovieJobTest() : s(options(), clock.fn()) {}

  // A 3-frame render job and its movie job, as Coordinator::record_job
  // makes them.
  void add_jobs(Scheduler& sched) {
    JobSpec r = test_doubles::job_spec(4, 4, 1, 3, 1);
    r.output = "shot_####.png";
    r.movie = "shot.mp4";
    r.fps = 12;
    r.owner = "ann";
    render = sched.add_job(r);
    JobSpec m;
    m.kind = JobKind::kMovie;
    m.scene_hash = r.scene_hash;
    m.width = r.width;
    m.height = r.height;
    m.frame_first = m.frame_last = 1;
    m.bands = 0;
    m.output = r.movie;
    m.fps = r.fps;
    m.owner = r.owner;
    m.after = {render};
    movie = sched.add_job(m);
  }
  void render_all(Scheduler& sched) {
    const std::string w = sched.add_worker("w", 1);
    for (;;) {
      auto lease = sched.next_band(w);
      ASSERT_TRUE(lease.ok());
      if (!*lease) break;
      auto r = sched.complete_band(pixels(w, **lease));
      ASSERT_TRUE(r.ok() && r->accepted);
      if (r->frame) sched.frame_written((*lease)->job_id, r->frame->frame, Status::Ok());
    }
  }

  FakeClock clock;
  Scheduler s;
  std::string render, movie;
};

TEST_F(MovieJobTest, WaitsForItsFramesThenSucceedsWithItsOneOutput) {
  add_jobs(s);
  EXPECT_EQ(s.job(render)->movie_job, movie);
  EXPECT_EQ(s.job(movie)->spec.bands_total(), 0);
  EXPECT_EQ(s.job(movie)->waiting, "waiting for job " + render + " (queued)");
  EXPECT_FALSE(s.next_movie().has_value());  // no frame yet
  // No worker ever gets a band of the movie job.
  render_all(s);
  EXPECT_EQ(s.job(render)->state, JobState::kSucceeded);
  auto task = s.next_movie();
  ASSERT_TRUE(task.has_value());
  EXPECT_EQ(task->job_id, movie);
  EXPECT_EQ(task->source_id, render);
  EXPECT_EQ(task->source.output, "shot_####.png");
  EXPECT_EQ(task->source.frame_first, 1);
  EXPECT_EQ(task->source.frame_last, 3);
  EXPECT_EQ(task->movie.output, "shot.mp4");
  EXPECT_EQ(task->movie.fps, 12);
  EXPECT_EQ(s.job(movie)->state, JobState::kRunning);
  EXPECT_FALSE(s.next_movie().has_value());  // one maker at a time
  EXPECT_TRUE(s.movie_done(movie, task->run, Status::Ok()));
  const JobInfo done = *s.job(movie);
  EXPECT_EQ(done.state, JobState::kSucceeded);
  EXPECT_EQ(done.frames_written, std::vector<int>{1});  // fetched like a frame
  EXPECT_FALSE(s.movie_done(movie, task->run, Status::Ok()));  // once
}

TEST_F(MovieJobTest, FailuresAreRetriedAfterBackOffThenFailTheJobWithTheReason) {
  add_jobs(s);
  render_all(s);
  auto first = s.next_movie();
  ASSERT_TRUE(first);
  EXPECT_TRUE(s.movie_done(movie, first->run, Internal("ffmpeg exited with status 1: boom")));
  EXPECT_EQ(s.job(movie)->state, JobState::kRunning);
  EXPECT_NE(s.job(movie)->waiting.find("attempt 2 in"), std::string::npos) << s.job(movie)->waiting;
  EXPECT_FALSE(s.next_movie().has_value());  // backing off: 1 s
  ASSERT_TRUE(s.next_movie_time().has_value());
  clock.advance(999);
  EXPECT_FALSE(s.next_movie().has_value());
  clock.advance(1);
  auto second = s.next_movie();
  ASSERT_TRUE(second);
  EXPECT_EQ(second->attempt, 2);
  EXPECT_NE(second->run, first->run);
  EXPECT_FALSE(s.movie_done(movie, first->run, Status::Ok()));  // a stale attempt counts not
  EXPECT_TRUE(s.movie_done(movie, second->run, Internal("again")));
  clock.advance(1999);  // then 2 s
  EXPECT_FALSE(s.next_movie().has_value());
  clock.advance(1);
  auto third = s.next_movie();
  ASSERT_TRUE(third);
  EXPECT_TRUE(s.movie_done(movie, third->run, Internal("ffmpeg exited with status 1: boom")));
  const JobInfo failed = *s.job(movie);
  EXPECT_EQ(failed.state, JobState::kFailed);
  EXPECT_EQ(failed.error, "movie: ffmpeg exited with status 1: boom (after 3 attempts)");
  EXPECT_FALSE(s.next_movie_time().has_value());
  // `locus retry`: fresh attempts.
  ASSERT_TRUE(s.retry(movie).ok());
  auto again = s.next_movie();
  ASSERT_TRUE(again);
  EXPECT_EQ(again->attempt, 1);
  EXPECT_TRUE(s.movie_done(movie, again->run, Status::Ok()));
  EXPECT_EQ(s.job(movie)->state, JobState::kSucceeded);
  // `locus requeue` of the movie job makes it again.
  ASSERT_TRUE(s.requeue(movie, std::nullopt, std::nullopt).ok());
  auto remade = s.next_movie();
  ASSERT_TRUE(remade);
  EXPECT_TRUE(s.movie_done(movie, remade->run, Status::Ok()));
  EXPECT_EQ(s.job(movie)->state, JobState::kSucceeded);
}

TEST_F(MovieJobTest, ACancelStopsTheMovieAndAFailedRenderJobFailsIt) {
  add_jobs(s);
  render_all(s);
  auto task = s.next_movie();
  ASSERT_TRUE(task);
  EXPECT_TRUE(s.movie_wanted(movie, task->run));
  ASSERT_TRUE(s.cancel(movie, "ann").ok());
  EXPECT_FALSE(s.movie_wanted(movie, task->run));  // the coordinator stops ffmpeg
  EXPECT_FALSE(s.movie_done(movie, task->run, Status(Code::kCancelled, "stopped")));
  EXPECT_EQ(s.job(movie)->state, JobState::kCancelled);

  Scheduler other(options(), clock.fn());
  add_jobs(other);
  ASSERT_TRUE(other.cancel(render, "ann").ok());
  const JobInfo m = *other.job(movie);
  EXPECT_EQ(m.state, JobState::kFailed);
  EXPECT_NE(m.error.find(render), std::string::npos) << m.error;
  EXPECT_FALSE(other.next_movie().has_value());
}

TEST_F(MovieJobTest, AMovieInTheMakingAtAKillIsMadeAgainAfterTheRestart) {
  TempDir dir;
  const std::string db = (dir.path / "locus.db").string();
  add_jobs(s);
  render_all(s);
  auto task = s.next_movie();
  ASSERT_TRUE(task);
  {
    auto store = JobStore::open(db);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE((*store)->apply(s.take_events()).ok());
  }
  // kill -9 here: the store says running.
  auto store = JobStore::open(db);
  ASSERT_TRUE(store.ok());
  auto state = (*store)->recover();
  ASSERT_TRUE(state.ok());
  Scheduler restarted(options(), clock.fn());
  restarted.restore(*state);
  const JobInfo m = *restarted.job(movie);
  EXPECT_EQ(m.spec.kind, JobKind::kMovie);
  EXPECT_EQ(m.spec.output, "shot.mp4");
  EXPECT_EQ(m.spec.fps, 12);
  EXPECT_EQ(m.spec.after, std::vector<std::string>{render});
  EXPECT_EQ(restarted.job(render)->movie_job, movie);
  EXPECT_EQ(restarted.job(render)->spec.movie, "shot.mp4");
  auto again = restarted.next_movie();
  ASSERT_TRUE(again);
  EXPECT_EQ(again->job_id, movie);
  EXPECT_EQ(again->source.output, "shot_####.png");
  EXPECT_TRUE(restarted.movie_done(movie, again->run, Status::Ok()));
  ASSERT_TRUE((*store)->apply(restarted.take_events()).ok());
  auto history = (*store)->history(movie, 0, 100);
  ASSERT_TRUE(history.ok());
  int making = 0;
  for (const HistoryEntry& h : *history) making += h.text.rfind("making the movie shot.mp4", 0) == 0;
  EXPECT_EQ(making, 2);  // before the kill and after the restart
}

TEST(MovieChecks, NamesRatesAndFrameTypes) {
  EXPECT_TRUE(check_movie("", 0, "a.exr").ok());  // no movie
  EXPECT_TRUE(check_movie("shot.mp4", 0, "s_####.png").ok());
  EXPECT_TRUE(check_movie("shot.WEBM", 30, "s_####.tif").ok());
  EXPECT_TRUE(check_movie("shot.gif", 240, "s_####.png").ok());
  for (const auto& [movie, fps, frames, says] :
       std::vector<std::tuple<std::string, int, std::string, std::string>>{
           {"shot.avi", 24, "s.png", "ends in .mp4"},
           {"out/shot.mp4", 24, "s.png", "plain file name"},
           {"..", 24, "s.png", "plain file name"},
           {"s_####.mp4", 24, "s.png", "no #### frame field"},
           {"shot.mp4", 241, "s.png", "fps 241"},
           {"shot.mp4", -1, "s.png", "fps -1"},
           {"shot.mp4", 24, "s_####.exr", "PNG or TIFF"}}) {
    const Status st = check_movie(movie, fps, frames);
    EXPECT_EQ(st.code(), Code::kInvalidArgument) << movie;
    EXPECT_NE(st.message().find(says), std::string::npos) << st.message();
  }
}

TEST(NotifyUrls, ParsedStrictlyAndAllowedOnlyUnderTheFarmsPrefixes) {
  auto u = parse_http_url("https://hooks.example:8443/locus/done?x=1", "url");
  ASSERT_TRUE(u.ok());
  EXPECT_TRUE(u->https);
  EXPECT_EQ(u->host, "hooks.example");
  EXPECT_EQ(u->port, 8443);
  EXPECT_EQ(u->path, "/locus/done?x=1");
  EXPECT_EQ(parse_http_url("http://[::1]/", "url")->host, "::1");
  EXPECT_EQ(parse_http_url("http://127.0.0.1", "url")->port, 80);
  for (const char* bad : {"ftp://x/", "http://", "http://a b/", "http://user@host/",
                          "http://host:0/", "http://host:99999/", "http://host/#frag",
                          "http://[::1/", "http://ho$t/", "javascript:alert(1)"}) {
    EXPECT_EQ(parse_http_url(bad, "url").status().code(), Code::kInvalidArgument) << bad;
  }
  const std::vector<std::string> allowed = {"http://127.0.0.1:8080/hooks",
                                            "https://ci.example/"};
  EXPECT_TRUE(check_notify_url("http://127.0.0.1:8080/hooks", allowed).ok());
  EXPECT_TRUE(check_notify_url("http://127.0.0.1:8080/hooks/j1?x", allowed).ok());
  EXPECT_TRUE(check_notify_url("https://CI.example/anything", allowed).ok());
  for (const char* refused :
       {"http://127.0.0.1:8080/hooksX", "http://127.0.0.1:8081/hooks", "https://127.0.0.1:8080/hooks",
        "http://127.0.0.1:8080@evil.example/hooks", "http://ci.example/", "http://10.0.0.1/"}) {
    EXPECT_NE(check_notify_url(refused, allowed).code(), Code::kOk) << refused;
  }
  EXPECT_EQ(check_notify_url("http://127.0.0.1:8080/hooks", {}).code(), Code::kPermissionDenied);
}

}  // namespace
}  // namespace locus::farm
