#include "worker/worker_client.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <thread>

#include "common/base/log.h"
#include "proto/wire/rpc.h"
#include "worker/band_renderer.h"
#include "worker/worker_metrics.h"

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
    install_band_log_capture();
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
  WorkerMetrics& metrics() { return metrics_; }
  // `locus drain`: like SIGTERM, the band in hand is finished and returned,
  // then run() returns 0. mu_ held.
  void drain_locked() {
    if (stopping_) return;
    spdlog::info(
        "drained by the coordinator (`locus drain`): finishing the band in hand, then "
        "exiting");
    stopping_ = true;
    if (poll_ctx_) poll_ctx_->TryCancel();
    cv_.notify_all();
  }

 private:
  using BandEnd = WorkerMetrics::BandEnd;
  bool register_worker();
  void heartbeat_loop();
  // Exits (o_.on_wedged) when a revoked band's render outlives
  // abandon_grace; mu_ held through `lk`.
  void check_wedged(std::unique_lock<std::mutex>& lk);
  // The coordinator took the band in hand (lease `id`) back: its render
  // stops (the cancellation flag, and the test's slowness), its result is
  // not sent, and --abandon-grace starts; mu_ held.
  void abandon_locked(const std::string& id, const std::string& why) {
    if (id.empty() || id != lease_ || revoked_ || sending_) return;
    revoked_ = true;
    revoked_at_ = SteadyClock::now();
    spdlog::info("lease {} {}; the band is abandoned", id, why);
    cv_.notify_all();
  }
  // Renders the leased band and returns it (or gives it back when stopping).
  void handle(const BandLease& band);
  // Nothing when the scene is at hand; otherwise how the band ended.
  std::optional<BandEnd> fetch_scene(const BandLease& band);
  BandEnd send(BandOutput output);
  // Ready: registered, and the last call reached the coordinator.
  void set_ready(bool ready) {
    {
      std::lock_guard lk(mu_);
      if (ready == ready_) return;
      ready_ = ready;
    }
    metrics_.set_connected(ready);
    if (o_.on_ready) o_.on_ready(ready);
  }
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
    set_ready(false);
  }

  WorkerOptions o_;
  WorkerMetrics metrics_;
  BandRenderer renderer_;
  rpc::Connection conn_;
  Status broken_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  std::string peer_;

  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool finished_ = false;  // run() is returning: no band in hand
  std::string worker_id_;
  Millis heartbeat_{1000};
  std::string lease_;  // the band in hand
  // ... which the coordinator took back (or the worker handed back). Also
  // render_band's cancellation flag: the render in hand stops within a row,
  // so a revoked band frees the worker. Written under mu_.
  std::atomic<bool> revoked_{false};
  TimePoint revoked_at_;  // when the coordinator took it back
  bool wedged_ = false;   // its render outlived abandon_grace: exiting
  bool sending_ = false;  // its result is on the way: a revocation now only echoes it
  grpc::ClientContext* poll_ctx_ = nullptr;
  // The next band, leased with the last result's answer
  // (CompleteBandRequest.want_next): run() takes it instead of a GetTask.
  // The run thread's alone (send() runs on it).
  std::optional<v1::GetTaskResponse> next_;
  bool outage_ = false;
  bool refused_ = false;
  bool ready_ = false;
};

bool WorkerClient::Impl::register_worker() {
  v1::RegisterRequest req;
  req.set_name(o_.name);
  req.set_threads(o_.threads);
  for (const std::string& t : o_.tags) req.add_tags(t);
  // PNG jobs' bands as PNG image data, EXR jobs' as EXR blocks
  // (common/farm/band_codec.h).
  req.add_encodings(v1::BAND_PNG8_DEFLATE);
  req.add_encodings(v1::BAND_EXR_ZIP);
  v1::RegisterResponse resp;
  grpc::ClientContext ctx;
  rpc::prepare(ctx, conn_, rpc::kShortCall);
  const Status s = rpc::FromGrpc(stub_->Register(&ctx, req, &resp), peer_);
  metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
  if (!s.ok()) {
    if (refused(s)) return false;
    unreachable(s);
    return false;
  }
  outage_ = false;
  metrics_.registered();
  {
    std::lock_guard lk(mu_);
    worker_id_ = resp.worker_id();
    heartbeat_ = Millis(std::max(50, resp.heartbeat_ms()));
    // The heartbeat thread waits the period it knew: it takes the new one
    // now, not after the default (a lease shorter than it would lapse).
    cv_.notify_all();
  }
  spdlog::info("registered with {} as {} ({}, {} threads per band)", o_.coordinator,
               resp.worker_id(), o_.name, o_.threads);
  set_ready(true);
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
      // A band leased with the last answer is handed back below, not
      // left to lapse.
      if (stopping_ && !next_) break;
      id = worker_id_;
    }
    if (id.empty()) next_.reset();  // leased to the registration that ended
    if (id.empty()) {
      if (!register_worker()) {
        pause(backoff);
        backoff = std::min(backoff * 2, Millis(2000));
      } else {
        backoff = Millis(100);
      }
      continue;
    }
    v1::GetTaskResponse resp;
    grpc::Status gs;
    if (next_) {
      // Leased with the last result's answer: no call.
      resp = std::move(*next_);
      next_.reset();
    } else {
      // GetTask (the wire's name): a long poll for the next band's lease.
      v1::GetTaskRequest req;
      req.set_worker_id(id);
      req.set_wait_ms(static_cast<int32_t>(o_.poll.count()));
      grpc::ClientContext ctx;
      rpc::prepare(ctx, conn_, o_.poll + rpc::kPollSlack);
      {
        std::lock_guard lk(mu_);
        if (stopping_) break;
        poll_ctx_ = &ctx;
      }
      gs = stub_->GetTask(&ctx, req, &resp);
      metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
      std::lock_guard lk(mu_);
      poll_ctx_ = nullptr;
    }
    {
      std::lock_guard lk(mu_);
      if (gs.ok() && resp.drain()) drain_locked();
      if (stopping_ && !resp.has_task()) break;
    }
    if (!gs.ok()) {
      const Status s = rpc::FromGrpc(gs, peer_);
      if (s.code() == Code::kNotFound) {
        // Dropped after silence, or the coordinator restarted: start afresh.
        spdlog::info("{}; registering again", s.message());
        set_ready(false);
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
    set_ready(true);
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
    finished_ = true;  // nothing in hand any more: the heartbeats end
    cv_.notify_all();
  }
  set_ready(false);
  heartbeats.join();
  return refused_ ? 1 : 0;
}

void WorkerClient::Impl::heartbeat_loop() {
  // Until run() returns, stopping or not: a worker that drains (SIGTERM,
  // `locus drain`) finishes the band in hand, whose lease must not lapse
  // meanwhile.
  std::unique_lock lk(mu_);
  while (!finished_) {
    const std::string known = worker_id_;
    cv_.wait_for(lk, heartbeat_, [&] { return finished_ || worker_id_ != known; });
    if (finished_ || worker_id_.empty()) continue;
    check_wedged(lk);
    v1::HeartbeatRequest req;
    req.set_worker_id(worker_id_);
    if (!lease_.empty()) req.add_lease_ids(lease_);
    const Millis period = heartbeat_;
    lk.unlock();
    v1::HeartbeatResponse resp;
    grpc::ClientContext ctx;
    rpc::prepare(ctx, conn_, std::max(period * 2, Millis(1000)));
    const grpc::Status gs = stub_->Heartbeat(&ctx, req, &resp);
    metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
    lk.lock();
    if (!gs.ok()) {
      // The main loop reports outages and re-registers. An unknown worker
      // (the coordinator restarted, or dropped this one) holds no lease
      // any more: the band in hand is abandoned like a revoked one, so
      // that its render stops and --abandon-grace applies.
      if (gs.error_code() == grpc::StatusCode::NOT_FOUND) {
        abandon_locked(lease_, "void: the coordinator no longer knows this worker (" +
                                   gs.error_message() + ")");
      }
      lk.unlock();
      refused(rpc::FromGrpc(gs, peer_));
      lk.lock();
      continue;
    }
    if (resp.drain()) drain_locked();
    for (const std::string& id : resp.revoked_lease_ids()) {
      abandon_locked(id, "revoked (band cancelled, lapsed or hung)");
    }
  }
}

void WorkerClient::Impl::check_wedged(std::unique_lock<std::mutex>& lk) {
  if (!revoked_ || lease_.empty() || sending_ || wedged_) return;
  const auto since = SteadyClock::now() - revoked_at_;
  if (since <= o_.abandon_grace) return;
  wedged_ = true;
  const std::string lease = lease_;
  lk.unlock();
  spdlog::critical(
      "the render of lease {} has not returned {:.1f} s after the band was revoked: exiting so "
      "that the supervisor restarts this worker",
      lease, std::chrono::duration<double>(since).count());
  if (o_.on_wedged) {
    o_.on_wedged();
  } else {
    spdlog::shutdown();
    std::_Exit(3);
  }
  lk.lock();
}

std::optional<WorkerClient::Impl::BandEnd> WorkerClient::Impl::fetch_scene(const BandLease& t) {
  if (renderer_.has_scene(t.scene_hash)) return std::nullopt;
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
  metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
  if (!s.ok()) {
    if (refused(s)) return BandEnd::kDropped;
    // The band's lease lapses and it goes to another worker (or this one
    // again once the coordinator is back).
    spdlog::warn("job {}: cannot fetch scene {}: {}", t.job_id, t.scene_hash.substr(0, 12),
                 s.message());
    return BandEnd::kDropped;
  }
  const Status added =
      renderer_.add_scene_bytes(t.scene_hash, resp.scene(), "job " + t.job_id + " scene");
  if (!added.ok()) {
    BandOutput o;
    o.error = added.message();
    return send(std::move(o));
  }
  metrics_.scene_fetched();
  spdlog::info("job {}: scene {} fetched ({} bytes)", t.job_id, t.scene_hash.substr(0, 12),
               resp.ByteSizeLong());
  return std::nullopt;
}

void WorkerClient::Impl::hand_back() {
  v1::CompleteBandRequest req;
  {
    std::lock_guard lk(mu_);
    if (lease_.empty() || sending_ || revoked_) return;
    revoked_ = true;  // whatever the render gives is not sent now
    // From now the render has abandon_grace to return (check_wedged); left
    // unset, the grace counted from the clock's epoch and a worker handing
    // back a band mid-row exited 3 as wedged.
    revoked_at_ = SteadyClock::now();
    req.set_worker_id(worker_id_);
    req.set_lease_id(lease_);
  }
  req.set_handed_back(true);
  v1::CompleteBandResponse resp;
  grpc::ClientContext ctx;
  rpc::prepare(ctx, conn_, Millis(3000));
  const Status s = rpc::FromGrpc(stub_->CompleteBand(&ctx, req, &resp), peer_);
  metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
  metrics_.band_ended(BandEnd::kHandedBack, -1);
  if (s.ok()) {
    spdlog::info("band of lease {} handed back", req.lease_id());
  } else {
    spdlog::warn("could not hand back lease {} ({}); it lapses instead", req.lease_id(),
                 s.message());
  }
}

void WorkerClient::Impl::handle(const BandLease& t) {
  // Every line logged about this band carries its ids.
  BandLogScope log_scope(t.job_id, t.frame, t.band);
  // ... and goes with its result to the coordinator (`locus logs`).
  BandLogCapture capture(t.job_id, t.frame, t.band);
  metrics_.band_started();
  if (o_.slow_band.count() > 0) {
    {
      // The test's slowness, like a render, ends when the band is revoked.
      std::unique_lock lk(mu_);
      cv_.wait_for(lk, o_.slow_band, [&] { return stopping_ || revoked_.load(); });
    }
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
  if (const std::optional<BandEnd> unrendered = fetch_scene(t)) {
    metrics_.band_ended(*unrendered, -1);
  } else {
    const auto start = SteadyClock::now();
    auto r = renderer_.render(t, &revoked_);
    const double seconds = std::chrono::duration<double>(SteadyClock::now() - start).count();
    BandOutput o;
    if (r.ok()) {
      o = std::move(*r);
    } else if (r.status().code() == Code::kCancelled) {
      // Revoked or handed back: send() drops it.
      o.error = r.status().message();
      spdlog::info("{}", o.error);
    } else {
      o.error = r.status().message();
      spdlog::warn("cannot render the band: {}", o.error);
    }
    o.log_lines = capture.take();
    const BandEnd end = send(std::move(o));
    metrics_.band_ended(end, seconds);
    if (end == BandEnd::kDone) spdlog::info("rendered in {:.3f} s and returned", seconds);
  }
  std::lock_guard lk(mu_);
  lease_.clear();
}

WorkerClient::Impl::BandEnd WorkerClient::Impl::send(BandOutput o) {
  {
    std::lock_guard lk(mu_);
    if (revoked_) return BandEnd::kDropped;
    sending_ = true;
    o.worker_id = worker_id_;
    o.lease_id = lease_;
  }
  const BandEnd sent = o.error.empty() ? BandEnd::kDone : BandEnd::kFailed;
  v1::CompleteBandRequest req = rpc::ToProto(std::move(o));
  {
    // The next band with the answer, unless this worker is stopping.
    std::lock_guard lk(mu_);
    req.set_want_next(!stopping_);
  }
  // A brief outage should not cost the band: retry while the lease may
  // still stand.
  for (int attempt = 0; attempt < 3; ++attempt) {
    v1::CompleteBandResponse resp;
    grpc::ClientContext ctx;
    rpc::prepare(ctx, conn_, rpc::kDataCall);
    const Status s = rpc::FromGrpc(stub_->CompleteBand(&ctx, req, &resp), peer_);
    metrics_.add_bytes(resp.ByteSizeLong(), req.ByteSizeLong());
    if (s.ok()) {
      if (resp.has_next()) next_ = std::move(*resp.mutable_next());
      if (!resp.accepted()) {
        spdlog::info("result for lease {} dropped: {}", req.lease_id(), resp.reason());
        return BandEnd::kDropped;
      }
      return sent;
    }
    if (refused(s)) return BandEnd::kDropped;
    if (s.code() != Code::kUnavailable && s.code() != Code::kDeadlineExceeded) {
      spdlog::warn("result for lease {} refused: {}", req.lease_id(), s.message());
      return BandEnd::kDropped;
    }
    unreachable(s);
    pause(Millis(500));
  }
  return BandEnd::kDropped;
}

WorkerClient::WorkerClient(WorkerOptions options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}
WorkerClient::~WorkerClient() = default;
int WorkerClient::run() { return impl_->run(); }
void WorkerClient::stop() { impl_->stop(); }
void WorkerClient::hand_back() { impl_->hand_back(); }
WorkerMetrics& WorkerClient::metrics() { return impl_->metrics(); }

}  // namespace locus::farm
