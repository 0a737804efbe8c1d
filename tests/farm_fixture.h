// The farm end to end inside one process, shared by the farm's loopback
// tests: a coordinator serving gRPC on 127.0.0.1 (ephemeral port), workers
// as threads, the CLI's FarmClient; frames compared, decoded, with
// single-process renders. By default the server is plaintext with client
// and worker tokens; set server_security_ (and the credentials) before
// start() for TLS.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <thread>

#include "client/farm_client.h"
#include "common/base/image.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "proto/locus.grpc.pb.h"
#include "proto/wire/rpc.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"
#include "worker/band_renderer.h"
#include "worker/worker_client.h"

namespace locus::farm::testing_farm {
namespace fs = std::filesystem;
using client::FarmClient;

inline const std::string kClientToken = "client-token-for-the-farm-tests";
inline const std::string kWorkerToken = "worker-token-for-the-farm-tests";

inline const std::string kBalls = std::string(LOCUS_SHARED_DIR) + "/spd/s1/balls.nff";
inline const std::string kSpheres = std::string(LOCUS_SOURCE_DIR) + "/scenes/simple/spheres.json";
inline const std::string kGlass = std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/a_glass.json";
inline const std::string kAnim =
    std::string(LOCUS_SOURCE_DIR) + "/scenes/anim/glass_and_mirror.json";
inline const std::string kTeapot = std::string(LOCUS_SOURCE_DIR) + "/scenes/teapot.json";

inline fs::path temp_dir() {
  std::string t = (fs::temp_directory_path() / "locus-farm-test-XXXXXX").string();
  EXPECT_NE(mkdtemp(t.data()), nullptr);
  return t;
}

inline SubmitRequest request(const std::string& path, int w, int h, int first, int last, int bands,
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
inline Image reference(const SubmitRequest& r, int frame, const fs::path& dir) {
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

  // Plaintext on loopback with a client and a worker token, unless the
  // test set server_security_ and the credentials otherwise.
  void start(Millis lease = Millis(3000)) {
    options_.data_dir = (dir_ / "data").string();
    options_.lease = lease;
    options_.heartbeat = lease / 4;
    options_.tick = Millis(20);
    coordinator_ = std::make_unique<Coordinator>(options_);
    ASSERT_TRUE(coordinator_->start().ok());
    server_ = std::make_unique<rpc::CoordinatorServer>(*coordinator_);
    auto port = server_->start("127.0.0.1:0", server_security_);
    ASSERT_TRUE(port.ok()) << port.status().message();
    address_ = "127.0.0.1:" + std::to_string(*port);
    client_ = std::make_unique<FarmClient>(address_, client_creds_);
  }

  // `tweak` adjusts each worker's options before it starts.
  void add_workers(int n, const std::function<void(WorkerOptions&)>& tweak = {}) {
    for (int i = 0; i < n; ++i) {
      WorkerOptions o;
      o.coordinator = address_;
      o.credentials = worker_creds_;
      o.threads = 1;
      o.poll = Millis(500);
      if (tweak) tweak(o);
      workers_.push_back(std::make_unique<WorkerClient>(o));
      threads_.emplace_back([w = workers_.back().get()] { w->run(); });
    }
  }

  // A raw WorkerService stub, as a worker (or an impostor) dials in.
  std::unique_ptr<v1::WorkerService::Stub> worker_stub(const Credentials& creds) {
    auto c = rpc::connect(address_, creds);
    EXPECT_TRUE(c.ok()) << c.status().message();
    connections_.push_back(*c);
    return v1::WorkerService::NewStub(c->channel);
  }
  // The deadline and token of a raw call, with the worker's credentials.
  void prepare(grpc::ClientContext& ctx, Millis timeout = Millis(5000)) {
    rpc::Connection c;
    c.token = worker_creds_.token;
    rpc::prepare(ctx, c, timeout);
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
  CoordinatorOptions options_;
  rpc::ServerSecurity server_security_ = [] {
    rpc::ServerSecurity s;
    s.insecure = true;
    s.auth = Authenticator::from_tokens({kClientToken}, {kWorkerToken});
    return s;
  }();
  Credentials client_creds_ = [] {
    Credentials c;
    c.token = kClientToken;
    return c;
  }();
  Credentials worker_creds_ = [] {
    Credentials c;
    c.token = kWorkerToken;
    return c;
  }();
  std::vector<rpc::Connection> connections_;
  std::string address_;
  std::unique_ptr<Coordinator> coordinator_;
  std::unique_ptr<rpc::CoordinatorServer> server_;
  std::unique_ptr<FarmClient> client_;
  std::vector<std::unique_ptr<WorkerClient>> workers_;
  std::vector<std::thread> threads_;
};

// The value of the sample `series` (name and labels, as written) in a text
// exposition, or -1 when absent.
inline double sample(const std::string& text, const std::string& series) {
  const std::string head = series + " ";
  for (size_t at = text.find(head); at != std::string::npos; at = text.find(head, at + 1)) {
    if (at == 0 || text[at - 1] == '\n') return std::stod(text.substr(at + head.size()));
  }
  return -1;
}

}  // namespace locus::farm::testing_farm
