// Movies and notifications (issue #26 items 1, 2) end to end in one
// process: a render job with --movie over loopback gRPC, its movie job made
// by the coordinator with Debian's ffmpeg (read back with ffprobe), an
// ffmpeg that fails once retried; a job's end POSTed to a receiver on
// 127.0.0.1 (retried after an HTTP 500, told after a restart when the
// receiver was down) and the coordinator's --notify-cmd run with the job
// in its environment.
#include <gtest/gtest.h>
#include <httplib.h>
#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <mutex>
#include <thread>

#include "common/farm/movie.h"
#include "server/notifier.h"
#include "tests/farm_fixture.h"

namespace locus::farm::testing_farm {
namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// What ffprobe says of the movie's video stream: "codec,w,h,rate,pix_fmt,frames".
std::string probe(const fs::path& movie) {
  const std::string cmd =
      "ffprobe -v error -select_streams v:0 -count_frames -show_entries "
      "stream=codec_name,width,height,r_frame_rate,pix_fmt,nb_read_frames -of csv=p=0 '" +
      movie.string() + "'";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return "";
  char buf[256] = {};
  std::string out;
  while (fgets(buf, sizeof buf, p)) out += buf;
  pclose(p);
  while (!out.empty() && (out.back() == '\n' || out.back() == '\r')) out.pop_back();
  return out;
}

int count(const std::vector<HistoryEntry>& events, const std::string& text) {
  int n = 0;
  for (const HistoryEntry& e : events) n += e.text.find(text) != std::string::npos;
  return n;
}

struct EnvVar {
  EnvVar(const char* name, const std::string& value) : name(name) { setenv(name, value.c_str(), 1); }
  ~EnvVar() { unsetenv(name); }
  const char* name;
};

TEST_F(FarmTest, AMovieJobFollowsItsRenderJobAndIsFetchedLikeAFrame) {
  start();
  add_workers(2);
  // ffmpeg fails its first run here (a wrapper), as a broken mount or a
  // full disk would: the movie job tries again after its back-off.
  const fs::path wrapper = dir_ / "ffmpeg-once-broken";
  const fs::path marker = dir_ / "ffmpeg-failed-once";
  {
    std::ofstream w(wrapper);
    w << "#!/bin/sh\nif [ ! -e '" << marker.string() << "' ]; then touch '" << marker.string()
      << "'; echo 'disk full (test)' >&2; exit 3; fi\nexec ffmpeg \"$@\"\n";
  }
  fs::permissions(wrapper, fs::perms::owner_all);
  EnvVar ffmpeg("LOCUS_FFMPEG", wrapper.string());
  SubmitRequest r = request(kSpheres, 48, 36, 1, 4, 2, "m_####.png", 30);
  r.movie = "m.mp4";
  r.fps = 8;
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();
  ASSERT_FALSE(job->movie_job.empty());
  auto movie = client_->job(job->movie_job);
  ASSERT_TRUE(movie.ok());
  EXPECT_EQ(movie->spec.kind, JobKind::kMovie);
  EXPECT_EQ(movie->spec.output, "m.mp4");
  EXPECT_EQ(movie->spec.after, std::vector<std::string>{job->job_id});
  auto done = client_->watch(job->movie_job, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok()) << done.status().message();
  ASSERT_EQ(done->state, JobState::kSucceeded) << done->error;
  // The render job's frames are those of one process; the movie is fetched.
  auto rendered = client_->job(job->job_id);
  ASSERT_TRUE(rendered.ok());
  expect_identical(*rendered, r);
  const fs::path got = dir_ / "movie";
  auto files = client_->fetch(done->job_id, {},
                              [&](int, const std::string& name) { return (got / name).string(); });
  ASSERT_TRUE(files.ok()) << files.status().message();
  EXPECT_EQ(probe(got / "m.mp4"), "h264,48,36,yuv420p,8/1,4");
  auto events = client_->events(done->job_id, 0);
  ASSERT_TRUE(events.ok());
  EXPECT_EQ(count(*events, "making the movie m.mp4 of frames 1-4 of job " + job->job_id), 2);
  EXPECT_EQ(count(*events, "the movie's attempt 1 failed: ffmpeg exited with status 3: disk full"),
            1);
}

TEST_F(FarmTest, MovieRequestsAreCheckedAtSubmission) {
  start();
  SubmitRequest r = request(kSpheres, 48, 36, 1, 2, 1, "m_####.exr");
  r.movie = "m.mp4";
  EXPECT_EQ(client_->submit(r).status().code(), Code::kInvalidArgument);
  r.output = "m_####.png";
  r.movie = "../m.mp4";
  EXPECT_EQ(client_->submit(r).status().code(), Code::kInvalidArgument);
  r.movie = "m.mov";
  EXPECT_EQ(client_->submit(r).status().code(), Code::kInvalidArgument);
  r.movie = "m.gif";
  r.fps = 1000;
  EXPECT_EQ(client_->submit(r).status().code(), Code::kInvalidArgument);
  r.notify_url = "http://127.0.0.1:1/x";  // allowed by no --notify-urls
  r.fps = 10;
  const auto refused = client_->submit(r);
  EXPECT_EQ(refused.status().code(), Code::kPermissionDenied);
  EXPECT_NE(refused.status().message().find("--notify-urls"), std::string::npos);
  EXPECT_TRUE(client_->jobs()->empty());  // nothing recorded
}

// A receiver of notifications on 127.0.0.1: answers 500 to the first
// `fail_first` POSTs, then 200; keeps the bodies it accepted.
class Receiver {
 public:
  explicit Receiver(int fail_first, int port = 0) : fail_first_(fail_first) {
    server_.Post("/hooks/locus", [this](const httplib::Request& req, httplib::Response& res) {
      std::lock_guard lk(mu_);
      if (posts_++ < fail_first_) {
        res.status = 500;
        return;
      }
      bodies_.push_back(req.body);
      res.status = 204;
    });
    port_ = port ? (server_.bind_to_port("127.0.0.1", port) ? port : -1)
                 : server_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    // stop() before listening begins would leave it listening for ever.
    for (int i = 0; i < 400 && port_ > 0 && !server_.is_running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ~Receiver() {
    server_.stop();
    thread_.join();
  }
  int port() const { return port_; }
  std::vector<std::string> bodies() {
    std::lock_guard lk(mu_);
    return bodies_;
  }
  int posts() {
    std::lock_guard lk(mu_);
    return posts_;
  }
  bool wait_for(size_t n) {
    for (int i = 0; i < 200 && bodies().size() < n; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    return bodies().size() >= n;
  }

 private:
  httplib::Server server_;
  std::mutex mu_;
  int fail_first_;
  int posts_ = 0;
  std::vector<std::string> bodies_;
  int port_ = -1;
  std::thread thread_;
};

class NotifyTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_dir(); }
  void TearDown() override {
    notifier_.reset();
    if (coordinator_) coordinator_->shutdown();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void start(int port, const std::string& command = "") {
    CoordinatorOptions o;
    o.data_dir = (dir_ / "data").string();
    o.tick = Millis(20);
    o.notify_urls = {"http://127.0.0.1:" + std::to_string(port) + "/hooks"};
    coordinator_ = std::make_unique<Coordinator>(o);
    rpc::NotifierOptions n;
    n.command = command;
    n.first_backoff = Millis(50);
    n.timeout = Millis(2000);
    notifier_ = std::make_unique<rpc::Notifier>(*coordinator_, n);
    ASSERT_TRUE(coordinator_->start().ok());
  }
  std::string submit(int port) {
    SubmitRequest r = request(kSpheres, 16, 12, 1, 1, 1, "n.png");
    r.notify_url = "http://127.0.0.1:" + std::to_string(port) + "/hooks/locus";
    auto job = coordinator_->submit(r, "ann");
    EXPECT_TRUE(job.ok()) << job.status().message();
    return job.ok() ? job->job_id : "";
  }
  std::vector<HistoryEntry> events(const std::string& job) {
    auto e = coordinator_->events(job, 0, 1000);
    EXPECT_TRUE(e.ok());
    return e.ok() ? *e : std::vector<HistoryEntry>{};
  }
  bool wait_events(const std::string& job, const std::string& text) {
    for (int i = 0; i < 200; ++i) {
      if (count(events(job), text) > 0) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    return false;
  }

  fs::path dir_;
  std::unique_ptr<Coordinator> coordinator_;
  std::unique_ptr<rpc::Notifier> notifier_;
};

TEST_F(NotifyTest, AJobsEndIsPostedAsJsonRetriedAfterAFailureAndTheCommandRuns) {
  Receiver receiver(1);
  ASSERT_GT(receiver.port(), 0);
  const fs::path told = dir_ / "told";
  start(receiver.port(), "echo \"$LOCUS_JOB_ID $LOCUS_JOB_STATE $LOCUS_JOB_KIND $LOCUS_JOB_OWNER\" >> '" +
                             told.string() + "'");
  const std::string job = submit(receiver.port());
  ASSERT_TRUE(coordinator_->cancel(job, Caller{"ann", false}).ok());
  ASSERT_TRUE(receiver.wait_for(1)) << "no notification arrived";
  EXPECT_EQ(receiver.posts(), 2);  // the 500, then the one accepted
  const std::string body = receiver.bodies()[0];
  EXPECT_NE(body.find("\"job_id\":\"" + job + "\""), std::string::npos) << body;
  EXPECT_NE(body.find("\"state\":\"JOB_STATE_CANCELLED\""), std::string::npos) << body;
  EXPECT_NE(body.find("\"owner\":\"ann\""), std::string::npos) << body;
  ASSERT_TRUE(wait_events(job, "notified http://127.0.0.1"));
  const auto history = events(job);
  EXPECT_EQ(count(history, "failed (attempt 1 of 6): HTTP 500"), 1);
  EXPECT_EQ(count(history, "notify command done"), 1);
  EXPECT_EQ(slurp(told), job + " cancelled render ann\n");
  // Jobs without a URL: only the command.
  SubmitRequest quiet = request(kSpheres, 16, 12, 1, 1, 1, "q.png");
  auto other = coordinator_->submit(quiet);
  ASSERT_TRUE(other.ok());
  ASSERT_TRUE(coordinator_->cancel(other->job_id).ok());
  ASSERT_TRUE(wait_events(other->job_id, "notify command done"));
  EXPECT_EQ(receiver.posts(), 2);
}

TEST_F(NotifyTest, AnEndNotToldBeforeAStopIsToldAfterTheRestart) {
  // A port with nobody listening: every POST is refused.
  int port;
  {
    Receiver probe(0);
    port = probe.port();
  }
  ASSERT_GT(port, 0);
  start(port);
  const std::string job = submit(port);
  ASSERT_TRUE(coordinator_->cancel(job).ok());
  ASSERT_TRUE(wait_events(job, "failed (attempt 1 of 6)"));
  notifier_.reset();
  coordinator_->crash_for_test();  // kill -9: the end is still pending in the store
  Receiver receiver(0, port);
  ASSERT_EQ(receiver.port(), port);
  start(port);
  ASSERT_TRUE(receiver.wait_for(1)) << "the pending notification was not sent after the restart";
  EXPECT_NE(receiver.bodies()[0].find("\"job_id\":\"" + job + "\""), std::string::npos);
  ASSERT_TRUE(wait_events(job, "notified"));
  // Told once: a third start sends nothing more.
  notifier_.reset();
  coordinator_->shutdown();
  start(port);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(receiver.posts(), 1);
}

}  // namespace
}  // namespace locus::farm::testing_farm
