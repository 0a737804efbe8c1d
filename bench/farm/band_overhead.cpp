// locus-farm-bench: the coordinator's cost per band with rendering taken
// out, and the bytes a band costs on the wire. Prints "key value" lines
// (bench/farm/run.sh turns them into bench/results/farm.md).
//   logic:  farm::Coordinator in process, a loop playing the worker
//           (lease_band + complete_band of zero pixels): dispatch + stitch.
//   grpc:   the same over gRPC on 127.0.0.1 (GetTask + CompleteBand).
//   bytes:  serialized sizes of a band's lease (GetTaskResponse) and of its
//           result.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "common/scene/scene_io.h"
#include "proto/locus.grpc.pb.h"
#include "proto/wire/rpc.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"

namespace {
using namespace locus;
using namespace locus::farm;
namespace fs = std::filesystem;

SubmitRequest trivial_job(int w, int h, int frames, int bands) {
  Scene s;
  s.has_camera = true;
  s.camera.width = w;
  s.camera.height = h;
  s.materials.push_back(Material{});
  Object o;
  o.shape = Sphere{};
  s.objects.push_back(o);
  SubmitRequest r;
  r.scene = scene_to_proto(s);
  r.scene_name = "trivial";
  r.width = w;
  r.height = h;
  r.frame_first = 1;
  r.frame_last = frames;
  r.bands = bands;
  r.output = "t_####.exr";
  return r;
}

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void wait_done(Coordinator& c, const std::string& job) {
  while (!is_terminal(c.job(job)->state)) std::this_thread::sleep_for(Millis(1));
}

}  // namespace

int main() {
  spdlog::set_level(spdlog::level::warn);
  const std::string dir = (fs::temp_directory_path() / "locus-farm-bench").string();
  fs::remove_all(dir);
  constexpr int kW = 64, kH = 48, kFrames = 100, kBands = 48;

  // ---- logic only
  {
    CoordinatorOptions o;
    o.data_dir = dir;
    Coordinator c(o);
    if (!c.start().ok()) return 1;
    const std::string worker = c.register_worker("bench", 1)->worker_id;
    auto job = c.submit(trivial_job(kW, kH, kFrames, kBands));
    if (!job.ok()) return 1;
    const double t0 = now_s();
    int bands = 0;
    for (;;) {
      auto t = c.lease_band(worker, Millis(0), nullptr);
      if (!t.ok() || !t->has_value()) break;
      BandOutput out;
      out.worker_id = worker;
      out.lease_id = (*t)->lease_id;
      out.rgb.assign(static_cast<size_t>(kW) * ((*t)->y1 - (*t)->y0) * 3, 0.0f);
      if (!c.complete_band(std::move(out)).ok()) return 1;
      ++bands;
    }
    const double t1 = now_s();
    wait_done(c, job->job_id);
    std::printf("logic_bands %d\nlogic_us_per_band %.2f\n", bands, (t1 - t0) * 1e6 / bands);
    c.shutdown();
  }

  // ---- over gRPC on loopback
  {
    CoordinatorOptions o;
    o.data_dir = dir;
    Coordinator c(o);
    if (!c.start().ok()) return 1;
    rpc::CoordinatorServer server(c);
    // As the embedded farm serves: plaintext on loopback, with a token
    // checked on every call.
    rpc::ServerSecurity security;
    security.insecure = true;
    security.auth = Authenticator::from_tokens({"bench-token"}, {"bench-token"});
    auto port = server.start("127.0.0.1:0", std::move(security));
    if (!port.ok()) return 1;
    Credentials creds;
    creds.token = "bench-token";
    auto conn = rpc::connect("127.0.0.1:" + std::to_string(*port), creds);
    if (!conn.ok()) return 1;
    auto stub = v1::WorkerService::NewStub(conn->channel);
    v1::RegisterResponse who;
    {
      grpc::ClientContext ctx;
      rpc::prepare(ctx, *conn, rpc::kShortCall);
      if (!stub->Register(&ctx, v1::RegisterRequest(), &who).ok()) return 1;
    }
    auto job = c.submit(trivial_job(kW, kH, kFrames, kBands));
    if (!job.ok()) return 1;
    const double t0 = now_s();
    int bands = 0;
    size_t lease_bytes = 0, result_bytes = 0;
    for (;;) {
      v1::GetTaskRequest get;
      get.set_worker_id(who.worker_id());
      get.set_wait_ms(0);
      v1::GetTaskResponse leased;  // GetTask: the wire's name for leasing a band
      grpc::ClientContext c1;
      rpc::prepare(c1, *conn, rpc::kShortCall);
      if (!stub->GetTask(&c1, get, &leased).ok() || !leased.has_task()) break;
      v1::CompleteBandRequest done;
      done.set_worker_id(who.worker_id());
      const v1::BandTask& band = leased.task();
      done.set_lease_id(band.lease_id());
      done.mutable_rgb()->Resize(kW * (band.y1() - band.y0()) * 3, 0.0f);
      lease_bytes = leased.ByteSizeLong();
      result_bytes = done.ByteSizeLong();
      v1::CompleteBandResponse ack;
      grpc::ClientContext c2;
      rpc::prepare(c2, *conn, rpc::kShortCall);
      if (!stub->CompleteBand(&c2, done, &ack).ok()) return 1;
      ++bands;
    }
    const double t1 = now_s();
    wait_done(c, job->job_id);
    std::printf("grpc_bands %d\ngrpc_us_per_band %.2f\n", bands, (t1 - t0) * 1e6 / bands);
    std::printf("bytes_lease %zu\nbytes_result_64x1 %zu\n", lease_bytes, result_bytes);
    server.shutdown(Millis(500));
  }

  // ---- bytes of a band's result at typical sizes (rows x width)
  for (auto [w, rows] : {std::pair{640, 30}, std::pair{1920, 68}}) {
    farm::BandOutput o;
    o.worker_id = "w0001";
    o.lease_id = "0123abcd-12345";
    o.rgb.assign(static_cast<size_t>(w) * rows * 3, 0.5f);
    std::printf("bytes_result_%dx%d %zu\n", w, rows, rpc::ToProto(std::move(o)).ByteSizeLong());
  }
  auto scene = load_scene(std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/a_glass.json");
  if (scene.ok()) std::printf("bytes_scene_a_glass %zu\n", scene_to_proto(*scene).ByteSizeLong());
  fs::remove_all(dir);
  return 0;
}
