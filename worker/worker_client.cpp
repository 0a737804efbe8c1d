#include "worker/worker_client.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "server/rpc.h"
#include "worker/band_renderer.h"

namespace locus::farm {
namespace {

std::string default_name() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host[0] ? host : "worker") + ":" + std::to_string(getpid());
}

}  // namespace

class WorkerClient::Impl {
 public:
  explicit Impl(WorkerOptions o) : o_(std::move(o)), renderer_(o_.threads, o_.mesh_root) {
    if (o_.name.empty()) o_.name = default_name();
    peer_ = "coordinator at " + o_.coordinator;
    auto c = rpc::connect(o_.coordinator, o_.credentials);
    if (!c.ok()) {
      broken_ = c.status();
      return;
    }
    conn_ = std::move(*c);
    stub_ = v1::WorkerService::NewStub(conn_.channel);
  }

  int run();

  void stop() {
    std::lock_guard lk(mu_);
    stopping_ = true;
    if (poll_ctx_) poll_ctx_->TryCancel();
    cv_.notify_all();
  }

  void hand_back();

 private:
  bool register_worker();
  void heartbeat_loop();
  void handle(const BandTask& task);
  bool fetch_scene(const BandTask& task);
  void send(BandOutput output);
  // Sleeps, but wakes at once on stop().
  void pause(Millis d) {
    std::unique_lock lk(mu_);
    cv_.wait_for(lk, d, [&] { return stopping_; });
  }
  // The coordinator refused this worker's credentials: no retry helps.
  bool refused(const Status& s) {
    if (s.code() != Code::kUnauthenticated && s.code() != Code::kPermissionDenied) return false;
    spdlog::error("{}; stopping (check the worker's token and certificate)", s.message());
    {
      std::lock_guard lk(mu_);
      refused_ = true;
    }
    stop();  // also ends a long poll in flight
    return true;
  }
  // One warning per outage, not one per retry.
  void unreachable(const Status& s) {
    if (!outage_) spdlog::warn("{}; retrying", s.message());
    outage_ = true;
  }

  WorkerOptions o_;
  BandRenderer renderer_;
  rpc::Connection conn_;
  Status broken_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  std::string peer_;

  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::string worker_id_;
  Millis heartbeat_{1000};
  std::string lease_;     // the band in hand
  bool revoked_ = false;  // ... which the coordinator took back
  bool sending_ = false;  // its result is on the way: a revocation now only echoes it
  grpc::ClientContext* poll_ctx_ = nullptr;
  bool outage_ = false;
  bool refused_ = false;
};

bool WorkerClient::Impl::register_worker() {
  v1::RegisterRequest req;
  req.set_name(o_.name);
  req.set_threads(o_.threads);
  v1::RegisterResponse resp;
  grpc::ClientContext ctx;
  rpc::prepare(ctx, conn_, rpc::kShortCall);
  const Status s = rpc::FromGrpc(stub_->Register(&ctx, req, &resp), peer_);
  if (!s.ok()) {
    if (refused(s)) return false;
    unreachable(s);
    return false;
  }
  outage_ = false;
  std::lock_guard lk(mu_);
  worker_id_ = resp.worker_id();
  heartbeat_ = Millis(std::max(50, resp.heartbeat_ms()));
  spdlog::info("registered with {} as {} ({}, {} threads per band)", o_.coordinator, worker_id_,
               o_.name, o_.threads);
  return true;
}

int WorkerClient::Impl::run() {
  if (!broken_.ok()) {
    spdlog::error("{}", broken_.message());
    return 1;
  }
  std::thread heartbeats([this] { heartbeat_loop(); });
  Millis backoff{100};
  for (;;) {
    std::string id;
    {
      std::lock_guard lk(mu_);
      if (stopping_) break;
      id = worker_id_;
    }
    if (id.empty()) {
      if (!register_worker()) {
        pause(backoff);
        backoff = std::min(backoff * 2, Millis(2000));
      } else {
        backoff = Millis(100);
      }
      continue;
    }
    v1::GetTaskRequest req;
    req.set_worker_id(id);
    req.set_wait_ms(static_cast<int32_t>(o_.poll.count()));
    v1::GetTaskResponse resp;
    grpc::ClientContext ctx;
    rpc::prepare(ctx, conn_, o_.poll + rpc::kPollSlack);
    {
      std::lock_guard lk(mu_);
      if (stopping_) break;
      poll_ctx_ = &ctx;
    }
    const grpc::Status gs = stub_->GetTask(&ctx, req, &resp);
    {
      std::lock_guard lk(mu_);
      poll_ctx_ = nullptr;
      if (stopping_ && !resp.has_task()) break;
    }
    if (!gs.ok()) {
      const Status s = rpc::FromGrpc(gs, peer_);
      if (s.code() == Code::kNotFound) {
        // Dropped after silence, or the coordinator restarted: start afresh.
        spdlog::info("{}; registering again", s.message());
        std::lock_guard lk(mu_);
        worker_id_.clear();
        continue;
      }
      if (refused(s)) break;
      unreachable(s);
      pause(backoff);
      backoff = std::min(backoff * 2, Millis(2000));
      continue;
    }
    outage_ = false;
    backoff = Millis(100);
    if (!resp.has_task()) continue;
    bool stopping;
    {
      std::lock_guard lk(mu_);
      stopping = stopping_;
      lease_ = resp.task().lease_id();
      revoked_ = false;
      sending_ = false;
    }
    // A band that arrived as the worker stops goes straight back.
    if (stopping) {
      hand_back();
      break;
    }
    handle(rpc::FromProto(resp.task()));
  }
  {
    std::lock_guard lk(mu_);
    stopping_ = true;
    cv_.notify_all();
  }
  heartbeats.join();
  return refused_ ? 1 : 0;
}

void WorkerClient::Impl::heartbeat_loop() {
  std::unique_lock lk(mu_);
  while (!stopping_) {
    cv_.wait_for(lk, heartbeat_, [&] { return stopping_; });
    if (stopping_ || worker_id_.empty()) continue;
    v1::HeartbeatRequest req;
    req.set_worker_id(worker_id_);
    if (!lease_.empty()) req.add_lease_ids(lease_);
    const Millis period = heartbeat_;
    lk.unlock();
    v1::HeartbeatResponse resp;
    grpc::ClientContext ctx;
    rpc::prepare(ctx, conn_, std::max(period * 2, Millis(1000)));
    const grpc::Status gs = stub_->Heartbeat(&ctx, req, &resp);
    lk.lock();
    if (!gs.ok()) {
      // The main loop reports outages and re-registers.
      lk.unlock();
      refused(rpc::FromGrpc(gs, peer_));
      lk.lock();
      continue;
    }
    for (const std::string& id : resp.revoked_lease_ids()) {
      if (id == lease_ && !revoked_ && !sending_) {
        revoked_ = true;
        spdlog::info("lease {} revoked (band cancelled or lapsed); its result will be dropped", id);
      }
    }
  }
}

bool WorkerClient::Impl::fetch_scene(const BandTask& t) {
  if (renderer_.has_scene(t.scene_hash)) return true;
  v1::GetSceneRequest req;
  req.set_scene_hash(t.scene_hash);
  {
    std::lock_guard lk(mu_);
    req.set_worker_id(worker_id_);
  }
  v1::GetSceneResponse resp;
  grpc::ClientContext ctx;
  rpc::prepare(ctx, conn_, rpc::kDataCall);
  const Status s = rpc::FromGrpc(stub_->GetScene(&ctx, req, &resp), peer_);
  if (!s.ok()) {
    if (refused(s)) return false;
    // The band's lease lapses and it goes to another worker (or this one
    // again once the coordinator is back).
    spdlog::warn("job {}: cannot fetch scene {}: {}", t.job_id, t.scene_hash.substr(0, 12),
                 s.message());
    return false;
  }
  const Status added =
      renderer_.add_scene(t.scene_hash, resp.scene(), "job " + t.job_id + " scene");
  if (!added.ok()) {
    BandOutput o;
    o.error = added.message();
    send(std::move(o));
    return false;
  }
  spdlog::info("job {}: scene {} fetched ({} bytes)", t.job_id, t.scene_hash.substr(0, 12),
               resp.ByteSizeLong());
  return true;
}

void WorkerClient::Impl::hand_back() {
  v1::CompleteBandRequest req;
  {
    std::lock_guard lk(mu_);
    if (lease_.empty() || sending_ || revoked_) return;
    revoked_ = true;  // whatever the render gives is not sent now
    req.set_worker_id(worker_id_);
    req.set_lease_id(lease_);
  }
  req.set_handed_back(true);
  v1::CompleteBandResponse resp;
  grpc::ClientContext ctx;
  rpc::prepare(ctx, conn_, Millis(3000));
  const Status s = rpc::FromGrpc(stub_->CompleteBand(&ctx, req, &resp), peer_);
  if (s.ok()) {
    spdlog::info("band of lease {} handed back", req.lease_id());
  } else {
    spdlog::warn("could not hand back lease {} ({}); it lapses instead", req.lease_id(),
                 s.message());
  }
}

void WorkerClient::Impl::handle(const BandTask& t) {
  if (o_.slow_band.count() > 0) {
    pause(o_.slow_band);
    bool stopping;
    {
      std::lock_guard lk(mu_);
      stopping = stopping_;
    }
    if (stopping) {  // not started yet: give it back rather than finish it
      hand_back();
      std::lock_guard lk(mu_);
      lease_.clear();
      return;
    }
  }
  if (fetch_scene(t)) {
    auto r = renderer_.render(t);
    BandOutput o;
    if (r.ok()) {
      o = std::move(*r);
    } else {
      o.error = r.status().message();
      spdlog::warn("job {} frame {} band {}: {}", t.job_id, t.frame, t.band, o.error);
    }
    send(std::move(o));
  }
  std::lock_guard lk(mu_);
  lease_.clear();
}

void WorkerClient::Impl::send(BandOutput o) {
  {
    std::lock_guard lk(mu_);
    if (revoked_) return;
    sending_ = true;
    o.worker_id = worker_id_;
    o.lease_id = lease_;
  }
  const v1::CompleteBandRequest req = rpc::ToProto(std::move(o));
  // A brief outage should not cost the band: retry while the lease may
  // still stand.
  for (int attempt = 0; attempt < 3; ++attempt) {
    v1::CompleteBandResponse resp;
    grpc::ClientContext ctx;
    rpc::prepare(ctx, conn_, rpc::kDataCall);
    const Status s = rpc::FromGrpc(stub_->CompleteBand(&ctx, req, &resp), peer_);
    if (s.ok()) {
      if (!resp.accepted())
        spdlog::info("result for lease {} dropped: {}", req.lease_id(), resp.reason());
      return;
    }
    if (refused(s)) return;
    if (s.code() != Code::kUnavailable && s.code() != Code::kDeadlineExceeded) {
      spdlog::warn("result for lease {} refused: {}", req.lease_id(), s.message());
      return;
    }
    unreachable(s);
    pause(Millis(500));
  }
}

WorkerClient::WorkerClient(WorkerOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}
WorkerClient::~WorkerClient() = default;
int WorkerClient::run() { return impl_->run(); }
void WorkerClient::stop() { impl_->stop(); }
void WorkerClient::hand_back() { impl_->hand_back(); }

}  // namespace locus::farm
