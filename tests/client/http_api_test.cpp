// The dashboard's JSON API (issue #24): HttpApi called directly (no HTTP
// socket) in front of a farm on loopback gRPC, then the cpp-httplib server on
// 127.0.0.1 with raw requests, hostile ones included. What is checked: no
// data without a token; the actions as the owner, refused to another user,
// allowed to an admin; JSON errors naming the problem (unknown fields, bad
// numbers, wrong methods, other origins); the limits; the images (the frame
// as written, a box-filtered thumbnail, a band of a frame in progress); the
// farm's cursor; the security headers.
#include "server/http_api.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <fstream>

#include "common/base/cost_map.h"
#include "server/http_server.h"
#include "tests/farm_fixture.h"
#include "tests/raw_http.h"
#include "tests/server/coordinator_doubles.h"

namespace locus::farm::testing_farm {
namespace {

const std::string kAnn = "Bearer ann-token-for-the-http-tests";
const std::string kBob = "Bearer bob-token-for-the-http-tests";
const std::string kRoot = "Bearer root-token-for-the-http-tests";

class HttpApiTest : public FarmTest {
 protected:
  void SetUp() override {
    FarmTest::SetUp();
    auth_ = Authenticator::from_tokens({"ann ann-token-for-the-http-tests",
                                        "bob bob-token-for-the-http-tests"},
                                       {kWorkerToken}, {"root root-token-for-the-http-tests"});
  }
  void make_api(rpc::HttpOptions o = {}) {
    handlers_ = std::make_unique<rpc::Handlers>(*coordinator_);
    api_ = std::make_unique<rpc::HttpApi>(*coordinator_, *handlers_, auth_, o);
  }
  rpc::HttpResponse call(const std::string& method, const std::string& path,
                         const std::string& auth = kAnn, const std::string& body = "",
                         const std::string& query = "") {
    rpc::HttpRequest r;
    r.method = method;
    r.path = path;
    r.query = query;
    r.authorization = auth;
    r.body = body;
    r.content_type = method == "POST" ? "application/json" : "";
    r.host = "127.0.0.1:1";
    r.remote = "127.0.0.1";
    return api_->handle(r);
  }
  // A job submitted over the API's own handler as `owner`.
  std::string submit(const SubmitRequest& r, const std::string& owner) {
    auto j = coordinator_->submit(r, owner);
    EXPECT_TRUE(j.ok()) << j.status().message();
    return j.ok() ? j->job_id : "";
  }
  Authenticator auth_;
  std::unique_ptr<rpc::Handlers> handlers_;
  std::unique_ptr<rpc::HttpApi> api_;
};

bool has_header(const rpc::HttpResponse& r, const std::string& name, const std::string& part) {
  for (const auto& [n, v] : r.headers) {
    if (n == name && v.find(part) != std::string::npos) return true;
  }
  return false;
}

TEST_F(HttpApiTest, NoTokenNoDataAndTheActionsFollowTheOwnersRules) {
  start();
  make_api();
  SubmitRequest r = request(kSpheres, 32, 24, 1, 2, 2, "http_####.png");
  r.scene_name = "<script>alert(1)</script>";
  const std::string job = submit(r, "ann");
  // Without a token, or with a wrong one: 401 and nothing of the job.
  for (const std::string& auth : {std::string(), std::string("Bearer nope"), std::string("x")}) {
    for (const std::string& path : std::vector<std::string>{
             "/api/v1/jobs", "/api/v1/farm", "/api/v1/jobs/" + job, "/api/v1/jobs/" + job + "/events"}) {
      const rpc::HttpResponse resp = call("GET", path, auth);
      EXPECT_EQ(resp.status, 401) << path;
      EXPECT_EQ(resp.body.find(job), std::string::npos) << resp.body;
      EXPECT_EQ(resp.body.find("script"), std::string::npos) << resp.body;
      EXPECT_TRUE(has_header(resp, "WWW-Authenticate", "Bearer"));
    }
  }
  EXPECT_EQ(call("POST", "/api/v1/jobs/" + job + "/pause", "").status, 401);
  // With ann's token: the job, its markup-laden name escaped in the JSON.
  const rpc::HttpResponse got = call("GET", "/api/v1/jobs/" + job);
  ASSERT_EQ(got.status, 200) << got.body;
  EXPECT_NE(got.body.find("\"owner\":\"ann\""), std::string::npos) << got.body;
  EXPECT_EQ(got.body.find("<script>"), std::string::npos) << got.body;
  EXPECT_TRUE(has_header(got, "Content-Security-Policy", "script-src 'self'"));
  EXPECT_TRUE(has_header(got, "Cache-Control", "no-store"));
  // Bob may read it but not pause it; ann and the admin may.
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job, kBob).status, 200);
  const rpc::HttpResponse denied = call("POST", "/api/v1/jobs/" + job + "/pause", kBob);
  EXPECT_EQ(denied.status, 403);
  EXPECT_NE(denied.body.find("PERMISSION_DENIED"), std::string::npos);
  EXPECT_NE(denied.body.find("belongs to ann"), std::string::npos) << denied.body;
  EXPECT_EQ(call("POST", "/api/v1/jobs/" + job + "/cancel", kBob).status, 403);
  EXPECT_NE(call("GET", "/api/v1/jobs/" + job).body.find("JOB_STATE_QUEUED"), std::string::npos);
  const rpc::HttpResponse paused = call("POST", "/api/v1/jobs/" + job + "/pause");
  ASSERT_EQ(paused.status, 200) << paused.body;
  EXPECT_NE(paused.body.find("JOB_STATE_PAUSED"), std::string::npos) << paused.body;
  // Read at once after the action: not the status kept from before it.
  EXPECT_NE(call("GET", "/api/v1/jobs/" + job).body.find("JOB_STATE_PAUSED"), std::string::npos);
  EXPECT_EQ(call("POST", "/api/v1/jobs/" + job + "/resume", kRoot).status, 200);
  EXPECT_EQ(call("POST", "/api/v1/jobs/" + job + "/priority", kAnn, R"({"priority": 80})").status,
            200);
  EXPECT_EQ(coordinator_->job(job)->spec.priority, 80);
  // Workers: admins only.
  EXPECT_EQ(call("POST", "/api/v1/workers/w0404/drain", kAnn).status, 403);
  EXPECT_EQ(call("POST", "/api/v1/workers/w0404/drain", kRoot).status, 404);
  // The history names who did what.
  const rpc::HttpResponse events = call("GET", "/api/v1/jobs/" + job + "/events");
  ASSERT_EQ(events.status, 200);
  EXPECT_NE(events.body.find("paused by ann"), std::string::npos) << events.body;
  EXPECT_NE(events.body.find("resumed by admin root"), std::string::npos) << events.body;
}

TEST_F(HttpApiTest, BadRequestsGetErrorsThatNameTheProblem) {
  start();
  rpc::HttpOptions o;
  o.rate = 5;
  o.burst = 40;
  make_api(o);
  const std::string job = submit(request(kSpheres, 32, 24, 1, 1, 1, "bad.png"), "ann");
  const auto expect = [&](const rpc::HttpResponse& r, int status, const std::string& words) {
    EXPECT_EQ(r.status, status) << r.body;
    EXPECT_NE(r.body.find(words), std::string::npos) << r.body;
    EXPECT_EQ(r.content_type, "application/json");
  };
  expect(call("POST", "/api/v1/jobs/" + job + "/priority", kAnn, R"({"priority": 80, "x": 1})"),
         400, "x");
  expect(call("POST", "/api/v1/jobs/" + job + "/priority", kAnn, R"({"priority": 101})"), 400,
         "priority");
  expect(call("POST", "/api/v1/jobs/" + job + "/priority", kAnn, "{not json"), 400,
         "request body");
  expect(call("GET", "/api/v1/jobs/" + job + "/pause"), 405, "not allowed");
  expect(call("POST", "/api/v1/jobs/" + job), 405, "not allowed");
  expect(call("GET", "/api/v1/jobs/j0404"), 404, "j0404");
  expect(call("GET", "/api/v1/nothing"), 404, "no such API route");
  expect(call("GET", "/api/v1/jobs/" + job + "/events", kAnn, "", "after=abc"), 400, "after");
  expect(call("GET", "/api/v1/jobs/" + job + "/frames/7"), 404, "frame 7");
  expect(call("GET", "/api/v1/jobs/" + job + "/frames/1/image"), 404, "not written");
  expect(call("GET", "/../../etc/passwd"), 404, "no such page");
  {
    rpc::HttpRequest r;
    r.method = "POST";
    r.path = "/api/v1/jobs/" + job + "/pause";
    r.authorization = kAnn;
    r.content_type = "application/x-www-form-urlencoded";
    r.remote = "127.0.0.1";
    expect(api_->handle(r), 415, "application/json");
    r.content_type = "application/json";
    r.origin = "http://evil.example";
    r.host = "127.0.0.1:1";
    expect(api_->handle(r), 403, "another origin");
    r.origin.clear();
    r.body.assign(70000, ' ');
    expect(api_->handle(r), 413, "over");
  }
  // The rate limit, per address: past the burst, 429; another address is
  // served; the job is intact.
  int refused = 0;
  for (int i = 0; i < 60; ++i) refused += call("GET", "/api/v1/jobs").status == 429;
  EXPECT_GT(refused, 0);
  rpc::HttpRequest other;
  other.method = "GET";
  other.path = "/api/v1/jobs/" + job;
  other.authorization = kAnn;
  other.remote = "127.0.0.2";
  EXPECT_EQ(api_->handle(other).status, 200);
  EXPECT_EQ(coordinator_->job(job)->state, JobState::kQueued);
}

TEST_F(HttpApiTest, FramesThumbnailsBandsAndTheFarmsCursor) {
  start();
  make_api();
  add_workers(2);
  SubmitRequest r = request(kGlass, 96, 72, 1, 2, 4, "img_####.png");
  const std::string job = submit(r, "ann");
  auto done = client_->watch(job, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  ASSERT_EQ(done->state, JobState::kSucceeded);
  // The frame: the written file's pixel values, in a PNG tagged for display.
  const rpc::HttpResponse image = call("GET", "/api/v1/jobs/" + job + "/frames/2/image");
  ASSERT_EQ(image.status, 200) << image.body;
  EXPECT_EQ(image.content_type, "image/png");
  const std::string frame_path = coordinator_->job_dir(job) + "/img_0002.png";
  {
    auto shown = read_image(image.file);
    auto written = read_image(frame_path);
    ASSERT_TRUE(shown.ok() && written.ok());
    EXPECT_EQ(shown->rgb, written->rgb);
  }
  // The thumbnail: at most 160 wide here (96: factor 1 would be the frame);
  // with 40 wide, a 3x3 box filter of the frame within 1/255.
  rpc::HttpOptions small;
  small.thumbnail_width = 40;
  make_api(small);
  const rpc::HttpResponse thumb = call("GET", "/api/v1/jobs/" + job + "/frames/2/thumbnail");
  ASSERT_EQ(thumb.status, 200) << thumb.body;
  auto t = read_image(thumb.file);
  auto f = read_image(frame_path);
  ASSERT_TRUE(t.ok() && f.ok());
  EXPECT_EQ(t->width, 32);
  EXPECT_EQ(t->height, 24);
  double worst = 0;
  for (int y = 0; y < t->height; ++y) {
    for (int x = 0; x < t->width; ++x) {
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int yy = 3 * y; yy < 3 * y + 3; ++yy)
          for (int xx = 3 * x; xx < 3 * x + 3; ++xx) sum += f->pixel(xx, yy)[c];
        worst = std::max(worst, std::abs(sum / 9 - t->pixel(x, y)[c]));
      }
    }
  }
  EXPECT_LE(worst, 1.0 / 255 + 1e-6);
  // The band map's data: every band done, with its worker, time and rays.
  const rpc::HttpResponse frame = call("GET", "/api/v1/jobs/" + job + "/frames/1");
  ASSERT_EQ(frame.status, 200);
  EXPECT_NE(frame.body.find("\"written\":true"), std::string::npos);
  size_t strips = 0;
  for (size_t at = frame.body.find("\"state\":\"done\""); at != std::string::npos;
       at = frame.body.find("\"state\":\"done\"", at + 1))
    ++strips;
  EXPECT_EQ(strips, 4u) << frame.body;
  EXPECT_NE(frame.body.find("\"rays_reflected\""), std::string::npos);
  // A band of a written frame has no band file any more: 404, not pixels.
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job + "/frames/1/bands/0/image").status, 404);
  // The cursor: unchanged at the current version, everything otherwise.
  const rpc::HttpResponse farm = call("GET", "/api/v1/farm");
  ASSERT_EQ(farm.status, 200);
  const size_t v = farm.body.find("\"version\":\"");
  ASSERT_NE(v, std::string::npos);
  const std::string version = farm.body.substr(v + 11, farm.body.find('"', v + 11) - v - 11);
  const rpc::HttpResponse same = call("GET", "/api/v1/farm", kAnn, "", "since=" + version);
  EXPECT_NE(same.body.find("\"unchanged\":true"), std::string::npos) << same.body;
  EXPECT_EQ(same.body.find(job), std::string::npos);
  // A worker's page: its leases.
  const rpc::HttpResponse w = call("GET", "/api/v1/workers/w0001");
  ASSERT_EQ(w.status, 200) << w.body;
  EXPECT_NE(w.body.find(job), std::string::npos);
}

// A job's cost maps (docs/cost-map.md "On the farm"): the frame's map as a
// PNG for the browser, the written map's values; none for a job without,
// nor for a frame not written, nor for another user's job.
TEST_F(HttpApiTest, AFramesCostMapIsServedForAJobThatMakesThem) {
  start();
  make_api();
  add_workers(2);
  SubmitRequest r = request(kGlass, 48, 36, 1, 1, 3, "cm_####.png");
  r.cost_map = "cost_####.exr";
  const std::string job = submit(r, "ann");
  const std::string plain = submit(request(kGlass, 16, 12, 1, 1, 1, "p_####.png"), "ann");
  for (const std::string& j : {job, plain}) {
    auto done = client_->watch(j, [](const JobInfo&) {});
    ASSERT_TRUE(done.ok());
    ASSERT_EQ(done->state, JobState::kSucceeded);
  }
  const rpc::HttpResponse map = call("GET", "/api/v1/jobs/" + job + "/frames/1/cost-map");
  ASSERT_EQ(map.status, 200) << map.body;
  EXPECT_EQ(map.content_type, "image/png");
  auto shown = read_image(map.file);
  auto written = read_image(coordinator_->job_dir(job) + "/cost_0001.exr");
  ASSERT_TRUE(shown.ok() && written.ok());
  ASSERT_EQ(shown->rgb.size(), written->rgb.size());
  double worst = 0;
  for (size_t i = 0; i < shown->rgb.size(); ++i)
    worst = std::max(worst, std::abs(double{shown->rgb[i]} - written->rgb[i]));
  EXPECT_LE(worst, 0.5 / 255 + 1e-6);  // the PNG's 8 bits of the EXR's values
  const rpc::HttpResponse none = call("GET", "/api/v1/jobs/" + plain + "/frames/1/cost-map");
  EXPECT_EQ(none.status, 404);
  EXPECT_NE(none.body.find("makes no cost maps"), std::string::npos) << none.body;
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job + "/frames/2/cost-map").status, 404);
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job + "/frames/1/cost-map", "").status, 401);
  // The job's status names the pattern.
  const rpc::HttpResponse status = call("GET", "/api/v1/jobs/" + job);
  EXPECT_NE(status.body.find("\"cost_map\":\"cost_####.exr\""), std::string::npos) << status.body;
}

// A frame in progress of a job with cost maps: frames/F/cost-map draws the
// bands accepted so far (their counts joined, the rest empty), says how
// many, and once the frame is written serves the written map.
TEST_F(HttpApiTest, AFrameInProgressShowsItsBandsCostsSoFar) {
  start();
  make_api();
  SubmitRequest r = request(kGlass, 40, 30, 1, 1, 2, "ip_####.png");
  r.cost_map = "ipc_####.png";
  const std::string job = submit(r, "ann");
  test_doubles::TestWorker w(*coordinator_, "w:1");
  const auto first = w.take();
  ASSERT_TRUE(first.has_value());
  ASSERT_TRUE(first->cost_map);  // the lease asks for the counts
  const BandOutput out = w.render(*first);
  ASSERT_FALSE(out.cost.empty());
  ASSERT_TRUE(coordinator_->complete_band(out).ok());
  const rpc::HttpResponse partial = call("GET", "/api/v1/jobs/" + job + "/frames/1/cost-map");
  ASSERT_EQ(partial.status, 200) << partial.body;
  EXPECT_TRUE(has_header(partial, "X-Locus-Bands-In", "1"));
  // The picture: the first band's own counts in its rows, nothing below.
  CostBuffer counts;
  counts.reset(40, 0, 30);
  auto band = decode_band_cost(out.cost, 40, first->y0, first->y1);
  ASSERT_TRUE(band.ok());
  std::copy(band->pixels.begin(), band->pixels.end(),
            counts.pixels.begin() + static_cast<size_t>(first->y0) * 40);
  const fs::path want_png = dir_ / "want.png", got_png = dir_ / "got.png";
  ASSERT_TRUE(write_image(want_png.string(), cost_map_image(counts), true).ok());
  ASSERT_TRUE(write_file(got_png.string(), partial.body).ok());
  auto want = read_image(want_png.string());
  auto got = read_image(got_png.string());
  ASSERT_TRUE(want.ok() && got.ok());
  EXPECT_EQ(got->rgb, want->rgb);
  // The second band: the frame is written, and its file is served.
  const auto second = w.take();
  ASSERT_TRUE(second.has_value());
  ASSERT_TRUE(w.complete(*second));
  for (int i = 0; i < 200 && coordinator_->job(job)->frames_done < 1; ++i)
    std::this_thread::sleep_for(Millis(10));
  const rpc::HttpResponse whole = call("GET", "/api/v1/jobs/" + job + "/frames/1/cost-map");
  ASSERT_EQ(whole.status, 200) << whole.body;
  EXPECT_FALSE(has_header(whole, "X-Locus-Bands-In", ""));
  auto shown = read_image(whole.file);
  auto written = read_image(coordinator_->job_dir(job) + "/ipc_0001.png");
  ASSERT_TRUE(shown.ok() && written.ok());
  EXPECT_EQ(shown->rgb, written->rgb);
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job + "/frames/9/cost-map").status, 404);
}

// A raw HTTP/1.1 exchange with 127.0.0.1:port: the whole answer.
std::string http_exchange(int port, const std::string& request, int timeout_seconds = 5) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return locus::testing::raw_http(a, request, timeout_seconds);
}

TEST_F(HttpApiTest, AMovieJobsMovieIsServedAsVideoAndItsFramesAreNotImages) {
  start();
  make_api();
  add_workers(2);
  SubmitRequest r = request(kSpheres, 32, 24, 1, 3, 1, "mv_####.png");
  r.movie = "mv.mp4";
  const std::string job = submit(r, "ann");
  const std::string movie = coordinator_->job(job)->movie_job;
  ASSERT_FALSE(movie.empty());
  auto done = client_->watch(movie, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  ASSERT_EQ(done->state, JobState::kSucceeded) << done->error;
  const auto status = call("GET", "/api/v1/jobs/" + movie);
  EXPECT_NE(status.body.find("\"kind\":\"movie\""), std::string::npos) << status.body;
  EXPECT_NE(call("GET", "/api/v1/jobs/" + job).body.find("\"movie_job\":\"" + movie + "\""),
            std::string::npos);
  const auto video = call("GET", "/api/v1/jobs/" + movie + "/frames/1/movie");
  EXPECT_EQ(video.status, 200) << video.body;
  EXPECT_EQ(video.content_type, "video/mp4");
  EXPECT_EQ(video.file, coordinator_->job_dir(movie) + "/mv.mp4");
  EXPECT_GT(fs::file_size(video.file), 0u);
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + movie + "/frames/1/movie", "").status, 401);
  // Not an image; and a render job has no movie of its own.
  const auto thumb = call("GET", "/api/v1/jobs/" + movie + "/frames/1/thumbnail");
  EXPECT_EQ(thumb.status, 404);
  EXPECT_NE(thumb.body.find("frames/1/movie"), std::string::npos) << thumb.body;
  EXPECT_EQ(call("GET", "/api/v1/jobs/" + job + "/frames/1/movie").status, 404);
  EXPECT_TRUE(has_header(video, "Content-Security-Policy", "media-src 'self' blob:"));
}

TEST_F(HttpApiTest, TheServerOnLoopbackAnswersAndSurvivesHostileRequests) {
  start();
  make_api();
  rpc::HttpServerOptions o;
  o.address = "127.0.0.1:0";
  auto server = rpc::HttpServer::start(o, *api_);
  ASSERT_TRUE(server.ok()) << server.status().message();
  const int port = (*server)->port();
  const std::string page = http_exchange(port, "GET / HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(page.rfind("HTTP/1.1 200", 0), 0u) << page.substr(0, 200);
  EXPECT_NE(page.find("Content-Security-Policy: default-src 'none'"), std::string::npos);
  EXPECT_NE(page.find("<script src=\"/app.js\""), std::string::npos);
  const std::string js = http_exchange(port, "GET /app.js HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_NE(js.find("Content-Type: text/javascript"), std::string::npos);
  EXPECT_EQ(http_exchange(port, "GET /api/v1/jobs HTTP/1.1\r\nHost: x\r\n\r\n").rfind("HTTP/1.1 401", 0),
            0u);
  const std::string jobs = http_exchange(port,
                                    "GET /api/v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: " +
                                        kAnn + "\r\n\r\n");
  EXPECT_EQ(jobs.rfind("HTTP/1.1 200", 0), 0u) << jobs.substr(0, 300);
  EXPECT_NE(jobs.find("{\"jobs\":[]}"), std::string::npos) << jobs;
  // Hostile input: garbage, an endless header, a body over the limit, a
  // body declared far larger than it is (the server gives up on it), then
  // a good one.
  http_exchange(port, std::string(5000, '\x01') + "\r\n\r\n");
  http_exchange(port, "GET / HTTP/1.1\r\nX: " + std::string(70000, 'a') + "\r\n\r\n");
  const std::string big = http_exchange(
      port, "POST /api/v1/jobs/j1/pause HTTP/1.1\r\nHost: x\r\nAuthorization: " + kAnn +
                "\r\nContent-Type: application/json\r\nContent-Length: 70000\r\n\r\n" +
                std::string(70000, ' '));
  EXPECT_EQ(big.rfind("HTTP/1.1 413", 0), 0u) << big.substr(0, 200);
  http_exchange(port,
                "POST /api/v1/jobs/j1/pause HTTP/1.1\r\nHost: x\r\nAuthorization: " + kAnn +
                    "\r\nContent-Type: application/json\r\nContent-Length: 99999999999\r\n\r\n{}",
                1);
  http_exchange(port, "GET /%2e%2e/%2e%2e/etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n");
  EXPECT_EQ(http_exchange(port, "GET /style.css HTTP/1.1\r\nHost: x\r\n\r\n").rfind("HTTP/1.1 200", 0),
            0u);
  EXPECT_TRUE(coordinator_->jobs().empty());
}

}  // namespace
}  // namespace locus::farm::testing_farm
