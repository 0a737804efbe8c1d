// The farm end to end inside one process: a coordinator serving gRPC on
// 127.0.0.1 (ephemeral port), workers as threads, the CLI's FarmClient.
// Frames are compared, decoded, with single-process renders.
#include <gtest/gtest.h>

#include <filesystem>
#include <thread>

#include "client/farm_client.h"
#include "common/image.h"
#include "common/render.h"
#include "common/scene_io.h"
#include "proto/locus.grpc.pb.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"
#include "server/rpc.h"
#include "worker/band_renderer.h"
#include "worker/worker_client.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using client::FarmClient;

const std::string kBalls = std::string(LOCUS_SHARED_DIR) + "/spd/s1/balls.nff";
const std::string kSpheres = std::string(LOCUS_SOURCE_DIR) + "/scenes/simple/spheres.json";
const std::string kGlass = std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/a_glass.json";
const std::string kAnim = std::string(LOCUS_SOURCE_DIR) + "/scenes/anim/glass_and_mirror.json";

fs::path temp_dir() {
  std::string t = (fs::temp_directory_path() / "locus-farm-test-XXXXXX").string();
  EXPECT_NE(mkdtemp(t.data()), nullptr);
  return t;
}

SubmitRequest request(const std::string& path, int w, int h, int first, int last, int bands,
                      const std::string& output, double orbit = 0) {
  auto scene = load_scene(path);
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  SubmitRequest r;
  r.scene = scene_to_proto(*scene);
  r.scene_name = path;
  r.width = w;
  r.height = h;
  r.frame_first = first;
  r.frame_last = last;
  r.bands = bands;
  r.output = output;
  r.orbit_degrees = orbit;
  return r;
}

// The single-process render of one frame, written and decoded like the
// farm's: the comparison is of decoded pixels.
Image reference(const SubmitRequest& r, int frame, const fs::path& dir) {
  auto scene = load_scene(r.scene_name);
  EXPECT_TRUE(scene.ok());
  const Scene s =
      frame_scene(*scene, r.width, r.height, frame, r.frame_first, r.frame_last, r.orbit_degrees);
  auto params = to_render_params(r.render, 1);
  auto img = render_image(s, *params);
  EXPECT_TRUE(img.ok()) << img.status().message();
  const fs::path out =
      dir / ("ref_" + std::to_string(frame) + fs::path(r.output).extension().string());
  EXPECT_TRUE(write_image(out.string(), img->pixels).ok());
  return *read_image(out.string());
}

class FarmTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = temp_dir(); }

  void TearDown() override {
    for (auto& w : workers_) w->stop();
    for (auto& t : threads_) t.join();
    if (server_) server_->shutdown(Millis(500));
    if (coordinator_) coordinator_->shutdown();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  void start(Millis lease = Millis(3000)) {
    CoordinatorOptions o;
    o.data_dir = (dir_ / "data").string();
    o.lease = lease;
    o.heartbeat = lease / 4;
    o.tick = Millis(20);
    coordinator_ = std::make_unique<Coordinator>(o);
    ASSERT_TRUE(coordinator_->start().ok());
    server_ = std::make_unique<rpc::CoordinatorServer>(*coordinator_);
    auto port = server_->start("127.0.0.1:0");
    ASSERT_TRUE(port.ok()) << port.status().message();
    address_ = "127.0.0.1:" + std::to_string(*port);
    client_ = std::make_unique<FarmClient>(address_);
  }

  void add_workers(int n) {
    for (int i = 0; i < n; ++i) {
      WorkerOptions o;
      o.coordinator = address_;
      o.threads = 1;
      o.poll = Millis(500);
      workers_.push_back(std::make_unique<WorkerClient>(o));
      threads_.emplace_back([w = workers_.back().get()] { w->run(); });
    }
  }

  JobInfo run(const SubmitRequest& r) {
    auto job = client_->submit(r);
    EXPECT_TRUE(job.ok()) << job.status().message();
    if (!job.ok()) return JobInfo();
    auto done = client_->watch(job->job_id, [](const JobInfo&) {});
    EXPECT_TRUE(done.ok()) << done.status().message();
    return done.ok() ? *done : JobInfo();
  }

  // Fetches the job's frames and compares each with a single-process render.
  void expect_identical(const JobInfo& job, const SubmitRequest& r) {
    ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;
    const fs::path got = dir_ / ("got_" + job.job_id);
    auto files = client_->fetch(
        job.job_id, {}, [&](int, const std::string& name) { return (got / name).string(); });
    ASSERT_TRUE(files.ok()) << files.status().message();
    ASSERT_EQ(files->size(), static_cast<size_t>(r.frame_last - r.frame_first + 1));
    for (int f = r.frame_first; f <= r.frame_last; ++f) {
      auto farm =
          read_image((got / frame_path(fs::path(r.output).filename().string(), f)).string());
      ASSERT_TRUE(farm.ok()) << farm.status().message();
      const Image ref = reference(r, f, dir_);
      ASSERT_EQ(farm->width, ref.width);
      ASSERT_EQ(farm->height, ref.height);
      size_t differ = 0;
      for (size_t i = 0; i < ref.rgb.size(); ++i) differ += farm->rgb[i] != ref.rgb[i];
      EXPECT_EQ(differ, 0u) << r.scene_name << " frame " << f << " bands " << job.spec.bands;
    }
  }

  fs::path dir_;
  std::string address_;
  std::unique_ptr<Coordinator> coordinator_;
  std::unique_ptr<rpc::CoordinatorServer> server_;
  std::unique_ptr<FarmClient> client_;
  std::vector<std::unique_ptr<WorkerClient>> workers_;
  std::vector<std::thread> threads_;
};

TEST_F(FarmTest, StitchedFramesEqualSingleProcessForAnySplit) {
  start();
  add_workers(2);
  for (const std::string& scene : {kBalls, kSpheres, kGlass}) {
    for (int bands : {1, 2, 3, 7, 48}) {  // 48: one band per row
      // EXR compares the linear floats themselves; PNG what users see.
      const std::string out = bands % 2 ? "f_####.exr" : "f_####.png";
      const SubmitRequest r = request(scene, 64, 48, 1, 1, bands, out);
      const JobInfo job = run(r);
      EXPECT_EQ(job.spec.bands, bands);
      expect_identical(job, r);
    }
  }
  // The paper's local method keeps per-row scanline state: bands must not
  // change it either.
  for (int bands : {2, 7, 48}) {
    SubmitRequest r = request(kGlass, 64, 48, 1, 1, bands, "l_####.exr");
    r.render.method = "local";
    r.render.boxes = "eye";
    expect_identical(run(r), r);
  }
  // Configuration IV with multi-scanning is the default.
  SubmitRequest aa = request(kGlass, 64, 48, 1, 1, 5, "aa_####.exr");
  ASSERT_EQ(aa.render.method, "local");
  ASSERT_EQ(aa.render.boxes, "eye+shadow");
  const JobInfo with_aa = run(aa);
  expect_identical(with_aa, aa);
  auto resolved = farm::to_render_params(aa.render, 1);
  ASSERT_TRUE(resolved.ok());
  EXPECT_EQ(resolved->aa, farm::kDefaultAa);
  // Point sampled, the job's stats are the sum of the bands' (with
  // multi-scanning each band computes its first sub-scanline again),
  // shadow-volume tests included.
  SubmitRequest r = request(kGlass, 64, 48, 1, 1, 5, "iv_####.exr");
  r.render.aa = 0;
  const JobInfo iv = run(r);
  expect_identical(iv, r);
  auto params = farm::to_render_params(r.render, 1);
  ASSERT_TRUE(params.ok());
  auto scene = load_scene(r.scene_name);
  ASSERT_TRUE(scene.ok());
  scene->camera.width = r.width;
  scene->camera.height = r.height;
  auto single = render_image(*scene, *params);
  ASSERT_TRUE(single.ok());
  EXPECT_GT(single->stats.tests_shadow_volume, 0u);
  EXPECT_EQ(iv.stats.tests_shadow_volume, single->stats.tests_shadow_volume);
  EXPECT_EQ(iv.stats.pixels_total, single->stats.pixels_total);
  EXPECT_EQ(iv.stats.shadow_method, "volumes");
}

TEST_F(FarmTest, TenFrameAnimationOverTwoWorkers) {
  start();
  add_workers(2);
  const SubmitRequest anim = request(kAnim, 64, 48, 1, 10, 0, "out/anim_####.png");
  const JobInfo job = run(anim);
  EXPECT_EQ(job.frames_done, 10);
  expect_identical(job, anim);
  // An NFF scene animated by the orbit alone.
  const SubmitRequest orbit = request(kBalls, 40, 30, 3, 6, 3, "orbit_##.png", 30.0);
  expect_identical(run(orbit), orbit);
  // Every worker took part, and each fetched each scene once.
  auto ws = client_->workers();
  ASSERT_TRUE(ws.ok());
  ASSERT_EQ(ws->size(), 2u);
  for (const WorkerInfo& w : *ws) EXPECT_GT(w.bands_done, 0) << w.worker_id;
}

TEST_F(FarmTest, ResultAfterLeaseExpiryIsIgnored) {
  start(Millis(300));
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 2, "s.png");
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();

  // A worker that takes a band and answers only after its lease lapsed.
  auto stub = v1::WorkerService::NewStub(rpc::make_channel(address_));
  grpc::ClientContext c1, c2, c3;
  rpc::set_deadline(c1, Millis(5000));
  v1::RegisterRequest reg;
  reg.set_name("slow");
  v1::RegisterResponse who;
  ASSERT_TRUE(stub->Register(&c1, reg, &who).ok());
  v1::GetTaskRequest get;
  get.set_worker_id(who.worker_id());
  get.set_wait_ms(2000);
  v1::GetTaskResponse task;
  rpc::set_deadline(c2, Millis(5000));
  ASSERT_TRUE(stub->GetTask(&c2, get, &task).ok());
  ASSERT_TRUE(task.has_task());
  // Alive (heartbeats) but not renewing the lease: it lapses.
  for (int i = 0; i < 7; ++i) {
    std::this_thread::sleep_for(Millis(100));
    grpc::ClientContext hc;
    rpc::set_deadline(hc, Millis(5000));
    v1::HeartbeatRequest hb;
    hb.set_worker_id(who.worker_id());
    v1::HeartbeatResponse hr;
    ASSERT_TRUE(stub->Heartbeat(&hc, hb, &hr).ok());
  }

  v1::CompleteBandRequest late;
  late.set_worker_id(who.worker_id());
  late.set_lease_id(task.task().lease_id());
  const int rows = task.task().y1() - task.task().y0();
  for (int i = 0; i < 32 * rows * 3; ++i) late.add_rgb(1.0f);  // a visibly wrong band
  v1::CompleteBandResponse answer;
  rpc::set_deadline(c3, Millis(5000));
  const grpc::Status st = stub->CompleteBand(&c3, late, &answer);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_FALSE(answer.accepted());
  EXPECT_NE(answer.reason().find("not held"), std::string::npos) << answer.reason();

  add_workers(1);
  auto done = client_->watch(job->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(done->bands_done, 2);
  expect_identical(*done, r);
}

TEST_F(FarmTest, CancelStopsTheWork) {
  start();
  add_workers(1);
  const SubmitRequest r = request(kSpheres, 64, 48, 1, 200, 48, "c_####.png");
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok());
  for (int i = 0; i < 500; ++i) {
    if (client_->job(job->job_id)->bands_done > 0) break;
    std::this_thread::sleep_for(Millis(10));
  }
  auto cancelled = client_->cancel(job->job_id);
  ASSERT_TRUE(cancelled.ok());
  EXPECT_EQ(cancelled->state, JobState::kCancelled);
  const int64_t at_cancel = cancelled->bands_done;
  std::this_thread::sleep_for(Millis(400));
  auto later = client_->job(job->job_id);
  EXPECT_EQ(later->state, JobState::kCancelled);
  EXPECT_EQ(later->bands_done, at_cancel);
  EXPECT_LT(at_cancel, 200 * 48);
  auto ws = client_->workers();
  ASSERT_TRUE(ws.ok());
  ASSERT_EQ(ws->size(), 1u);
  EXPECT_FALSE((*ws)[0].busy);
  // A watch of a cancelled job ends at once with its state.
  auto watched = client_->watch(job->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(watched.ok());
  EXPECT_EQ(watched->state, JobState::kCancelled);
}

TEST_F(FarmTest, BadSubmissionsGetClearErrorsAndStoreNothing) {
  start();
  SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 0, "x.png");
  r.scene.mutable_objects(1)->mutable_sphere()->set_radius(-1.0);
  auto bad = client_->submit(r);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), Code::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("objects[1]"), std::string::npos) << bad.status().message();
  EXPECT_NE(bad.status().message().find("radius"), std::string::npos) << bad.status().message();

  SubmitRequest frames = request(kSpheres, 32, 24, 1, 5, 0, "still.png");
  auto no_field = client_->submit(frames);
  EXPECT_EQ(no_field.status().code(), Code::kInvalidArgument);
  EXPECT_NE(no_field.status().message().find("####"), std::string::npos)
      << no_field.status().message();

  SubmitRequest rows = request(kSpheres, 32, 24, 1, 1, 25, "x.png");
  EXPECT_EQ(client_->submit(rows).status().code(), Code::kInvalidArgument);
  SubmitRequest ext = request(kSpheres, 32, 24, 1, 1, 0, "x.jpg");
  EXPECT_NE(client_->submit(ext).status().message().find(".jpg"), std::string::npos);
  SubmitRequest control = request(kSpheres, 32, 24, 1, 1, 0, "x\x01y.png");
  EXPECT_EQ(client_->submit(control).status().code(), Code::kInvalidArgument);
  SubmitRequest size = request(kSpheres, 99999, 24, 1, 1, 0, "x.png");
  EXPECT_EQ(client_->submit(size).status().code(), Code::kInvalidArgument);
  SubmitRequest back = request(kSpheres, 32, 24, 5, 1, 0, "x_#.png");
  EXPECT_EQ(client_->submit(back).status().code(), Code::kInvalidArgument);
  SubmitRequest obj = request(kSpheres, 32, 24, 1, 1, 0, "x.png");
  obj.scene.mutable_objects(0)->mutable_mesh()->set_obj("/etc/passwd");
  EXPECT_EQ(client_->submit(obj).status().code(), Code::kInvalidArgument);
  // Each method's own anti-aliasing: --spp for raytrace, --aa for local.
  SubmitRequest spp = request(kSpheres, 32, 24, 1, 1, 0, "x.png");
  spp.render.spp = 4;
  EXPECT_NE(client_->submit(spp).status().message().find("--spp 4"), std::string::npos);
  SubmitRequest aa = request(kSpheres, 32, 24, 1, 1, 0, "x.png");
  aa.render.method = "raytrace";
  aa.render.aa = 2;
  EXPECT_NE(client_->submit(aa).status().message().find("--aa 2"), std::string::npos);
  aa.render.method = "local";
  aa.render.aa = kMaxAa + 1;
  EXPECT_EQ(client_->submit(aa).status().code(), Code::kInvalidArgument);

  auto jobs = client_->jobs();
  ASSERT_TRUE(jobs.ok());
  EXPECT_TRUE(jobs->empty());
}

TEST_F(FarmTest, UnknownJobsAndMalformedWorkerCallsAreRefused) {
  start();
  EXPECT_EQ(client_->job("j9999").status().code(), Code::kNotFound);
  EXPECT_NE(client_->job("j9999").status().message().find("unknown"), std::string::npos);
  EXPECT_EQ(client_->cancel("").status().code(), Code::kInvalidArgument);
  auto fetch =
      client_->fetch("nope", {}, [](int, const std::string&) { return std::string("/dev/null"); });
  EXPECT_EQ(fetch.status().code(), Code::kNotFound);

  auto stub = v1::WorkerService::NewStub(rpc::make_channel(address_));
  {
    grpc::ClientContext ctx;
    rpc::set_deadline(ctx, Millis(5000));
    v1::GetTaskRequest req;
    req.set_worker_id("w-unknown");
    v1::GetTaskResponse resp;
    EXPECT_EQ(stub->GetTask(&ctx, req, &resp).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  {
    grpc::ClientContext ctx;
    rpc::set_deadline(ctx, Millis(5000));
    v1::CompleteBandRequest req;  // no ids at all
    v1::CompleteBandResponse resp;
    EXPECT_EQ(stub->CompleteBand(&ctx, req, &resp).error_code(),
              grpc::StatusCode::INVALID_ARGUMENT);
  }
  {
    // Pixels of the wrong size for a real lease: refused, band re-queued.
    SubmitRequest r = request(kSpheres, 16, 8, 1, 1, 1, "m.png");
    ASSERT_TRUE(client_->submit(r).ok());
    grpc::ClientContext c1, c2, c3;
    for (auto* c : {&c1, &c2, &c3}) rpc::set_deadline(*c, Millis(5000));
    v1::RegisterResponse who;
    ASSERT_TRUE(stub->Register(&c1, v1::RegisterRequest(), &who).ok());
    v1::GetTaskRequest get;
    get.set_worker_id(who.worker_id());
    get.set_wait_ms(1000);
    v1::GetTaskResponse task;
    ASSERT_TRUE(stub->GetTask(&c2, get, &task).ok());
    ASSERT_TRUE(task.has_task());
    v1::CompleteBandRequest wrong;
    wrong.set_worker_id(who.worker_id());
    wrong.set_lease_id(task.task().lease_id());
    wrong.add_rgb(0.5f);
    v1::CompleteBandResponse resp;
    const grpc::Status st = stub->CompleteBand(&c3, wrong, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("expected 384 floats"), std::string::npos)
        << st.error_message();
  }
}

TEST(FarmClient, UnreachableFarmSaysSo) {
  FarmClient farm("127.0.0.1:1");
  auto r = farm.jobs();
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kUnavailable);
  EXPECT_NE(r.status().message().find("cannot reach the farm at 127.0.0.1:1"), std::string::npos)
      << r.status().message();
}

TEST(BandRenderer, RendersBandsOfOneFramePreparingOnce) {
  auto scene = load_scene(kSpheres);
  ASSERT_TRUE(scene.ok());
  BandRenderer renderer(1);
  ASSERT_TRUE(renderer.add_scene("h", scene_to_proto(*scene), "spheres").ok());
  BandTask t;
  t.scene_hash = "h";
  t.frame = 1;
  t.width = 32;
  t.height = 24;
  t.frame_first = t.frame_last = 1;
  std::vector<float> stitched;
  for (int b = 0; b < 3; ++b) {
    t.y0 = b * 8;
    t.y1 = b * 8 + 8;
    auto out = renderer.render(t);
    ASSERT_TRUE(out.ok()) << out.status().message();
    EXPECT_EQ(out->rgb.size(), 32u * 8 * 3);
    stitched.insert(stitched.end(), out->rgb.begin(), out->rgb.end());
  }
  EXPECT_EQ(renderer.prepares(), 1);
  const Scene s = frame_scene(*scene, 32, 24, 1, 1, 1, 0);
  auto whole = render_image(s, *to_render_params(RenderSettings(), 1));
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(stitched, whole->pixels.rgb);

  t.y1 = 25;  // past the frame
  EXPECT_EQ(renderer.render(t).status().code(), Code::kInvalidArgument);
  t.scene_hash = "other";
  EXPECT_EQ(renderer.render(t).status().code(), Code::kFailedPrecondition);
}

}  // namespace
}  // namespace locus::farm
