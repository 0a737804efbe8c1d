#include "bench/farm/sim_worker.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

#include "common/farm/band_codec.h"
#include "common/farm/types.h"
#include "proto/wire/rpc.h"

namespace locus::farm_scale {

std::shared_ptr<const std::string> Shared::payload(const v1::BandTask& task) {
  const int y0 = task.y0(), y1 = task.y1();
  const auto encoding = static_cast<locus::farm::BandEncoding>(task.encoding());
  std::lock_guard lk(mu);
  auto& p = payloads[{y0, y1, static_cast<int>(encoding)}];
  if (!p) {
    locus::farm::BandOutput out;
    const size_t begin = static_cast<size_t>(y0) * width * 3;
    const size_t end = static_cast<size_t>(y1) * width * 3;
    out.rgb.assign(frame.begin() + static_cast<std::ptrdiff_t>(begin),
                   frame.begin() + static_cast<std::ptrdiff_t>(end));
    if (encoding != locus::farm::BandEncoding::kFloat32) {
      auto encoded = locus::farm::encode_band(encoding, width, y1 - y0, out.rgb);
      if (!encoded.ok()) {
        std::fprintf(stderr, "encode: %s\n", encoded.status().message().c_str());
        std::_Exit(2);
      }
      out.encoded = std::move(*encoded);
      out.rgb.clear();
    }
    p = std::make_shared<const std::string>(
        locus::rpc::ToProto(std::move(out)).SerializeAsString());
  }
  return p;
}

SimWorker::SimWorker(Shared& shared, int index, Behaviour behaviour)
    : s_(shared), index_(index), behaviour_(behaviour), rng_(static_cast<unsigned>(index) + 1) {
  connect();
}

void SimWorker::connect() {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetMaxSendMessageSize(64 << 20);
  channel_ = grpc::CreateCustomChannel(s_.address, grpc::InsecureChannelCredentials(), args);
  stub_ = v1::WorkerService::NewStub(channel_);
}

bool SimWorker::start() {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  const v1::RegisterRequest req = registration();
  v1::RegisterResponse resp;
  const grpc::Status st = stub_->Register(&ctx, req, &resp);
  if (!st.ok()) {
    std::fprintf(stderr, "worker %d: Register: %s\n", index_, st.error_message().c_str());
    return false;
  }
  registered(resp);
  return true;
}

void SimWorker::poll() {
  if (s_.stopping || dead_) return;
  auto call = std::make_shared<Call<v1::GetTaskRequest, v1::GetTaskResponse>>(Ms(15000));
  call->req.set_worker_id(id_);
  call->req.set_wait_ms(10000);
  call->req.set_max_bands(s_.batch);
  track(call->ctx.get());
  {
    std::lock_guard lk(s_.mu);
    ++s_.get_tasks;
  }
  const auto sent = Clock::now();
  stub_->async()->GetTask(call->ctx.get(), &call->req, &call->resp,
                          [this, call, sent](grpc::Status st) {
                            untrack(call->ctx.get());
                            on_task(call->resp, st, sent);
                          });
}

void SimWorker::heartbeat() {
  std::vector<std::string> leases;
  {
    std::lock_guard lk(mu_);
    leases = leases_;
  }
  if (leases.empty() || dead_ || behaviour_ != Behaviour::kNormal || s_.stopping) return;
  auto call = std::make_shared<Call<v1::HeartbeatRequest, v1::HeartbeatResponse>>(Ms(5000));
  call->req.set_worker_id(id_);
  for (const std::string& l : leases) call->req.add_lease_ids(l);
  track(call->ctx.get());
  stub_->async()->Heartbeat(call->ctx.get(), &call->req, &call->resp,
                            [this, call](grpc::Status) { untrack(call->ctx.get()); });
  std::lock_guard lk(s_.mu);
  ++s_.heartbeats;
}

void SimWorker::stop() {
  std::lock_guard lk(mu_);
  for (grpc::ClientContext* c : in_flight_) c->TryCancel();
}

size_t SimWorker::in_flight() {
  std::lock_guard lk(mu_);
  return in_flight_.size();
}

void SimWorker::track(grpc::ClientContext* c) {
  std::lock_guard lk(mu_);
  in_flight_.push_back(c);
}

void SimWorker::untrack(grpc::ClientContext* c) {
  std::lock_guard lk(mu_);
  in_flight_.erase(std::find(in_flight_.begin(), in_flight_.end(), c));
}

void SimWorker::retry_later() {
  s_.timers->at(Clock::now() + Ms(100), [this] { poll(); });
}

v1::RegisterRequest SimWorker::registration() const {
  v1::RegisterRequest req;
  req.set_name("sim-" + std::to_string(index_));
  req.set_threads(1);
  if (s_.png_deflate) req.add_encodings(v1::BAND_PNG8_DEFLATE);
  return req;
}

void SimWorker::registered(const v1::RegisterResponse& resp) {
  std::lock_guard lk(mu_);
  id_ = resp.worker_id();
  lease_ms_ = resp.lease_ms();
}

void SimWorker::register_again() {
  if (s_.stopping) return;
  {
    std::lock_guard lk(s_.mu);
    ++s_.registrations;
  }
  auto call = std::make_shared<Call<v1::RegisterRequest, v1::RegisterResponse>>(Ms(30000));
  call->req = registration();
  track(call->ctx.get());
  stub_->async()->Register(call->ctx.get(), &call->req, &call->resp, [this, call](grpc::Status st) {
    untrack(call->ctx.get());
    if (st.ok()) {
      registered(call->resp);
      poll();
      return;
    }
    if (!outage(st)) {
      std::lock_guard lk(s_.mu);
      ++s_.errors;
      if (s_.errors <= 5)
        std::fprintf(stderr, "worker %d: Register: %s\n", index_, st.error_message().c_str());
    } else if (!s_.stopping) {
      register_again_later();  // the coordinator is away
    }
  });
}

void SimWorker::register_again_later() {
  s_.timers->at(Clock::now() + Ms(500), [this] { register_again(); });
}

bool SimWorker::outage(const grpc::Status& st) {
  if (!s_.outage_ok) return false;
  const auto code = st.error_code();
  if (code != grpc::StatusCode::UNAVAILABLE && code != grpc::StatusCode::DEADLINE_EXCEEDED &&
      code != grpc::StatusCode::CANCELLED)
    return false;
  std::lock_guard lk(s_.mu);
  ++s_.outage_errors;
  return true;
}

void SimWorker::on_task(const v1::GetTaskResponse& resp, const grpc::Status& st,
                        std::optional<Clock::time_point> sent) {
  if (s_.stopping) return;
  if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
    register_again();
    return;
  }
  if (!st.ok()) {
    if (!outage(st)) {
      std::lock_guard lk(s_.mu);
      ++s_.errors;
      if (s_.errors <= 5)
        std::fprintf(stderr, "worker %d: GetTask: %s\n", index_, st.error_message().c_str());
    }
    s_.timers->at(Clock::now() + Ms(100), [this] { poll(); });
    return;
  }
  if (!resp.has_task()) {
    poll();
    return;
  }
  // The band, and the further ones of a batch (--batch).
  std::vector<v1::BandTask> tasks{resp.task()};
  tasks.insert(tasks.end(), resp.more().begin(), resp.more().end());
  if (sent) {
    std::lock_guard lk(s_.mu);
    s_.dispatch_ms.push_back(seconds_since(*sent) * 1000);
  }
  {
    std::lock_guard lk(mu_);
    leases_.clear();
    for (const v1::BandTask& t : tasks) leases_.push_back(t.lease_id());
  }
  if (behaviour_ == Behaviour::kDie) {
    // A killed host: its connection goes, its band is never returned.
    dead_ = true;
    stop();
    if (s_.revive_ms > 0) {
      // ... and comes back (a restarted host): a new connection, a new
      // registration; it dies again after its next lease.
      s_.timers->at(Clock::now() + Ms(s_.revive_ms), [this] {
        if (s_.stopping) return;
        connect();
        has_scene_ = false;
        dead_ = false;
        {
          std::lock_guard lk(s_.mu);
          ++s_.revived;
        }
        register_again();
      });
    }
    return;
  }
  if (behaviour_ == Behaviour::kStall) {
    dead_ = true;  // alive, connected, silent
    return;
  }
  if (!has_scene_) {
    fetch_scene(std::move(tasks));
    return;
  }
  after_delay(std::move(tasks));
}

void SimWorker::fetch_scene(std::vector<v1::BandTask> tasks) {
  auto call = std::make_shared<Call<v1::GetSceneRequest, v1::GetSceneResponse>>(Ms(30000));
  call->req.set_worker_id(id_);
  call->req.set_scene_hash(tasks.front().scene_hash());
  track(call->ctx.get());
  stub_->async()->GetScene(call->ctx.get(), &call->req, &call->resp,
                           [this, call, tasks](grpc::Status st) {
                             untrack(call->ctx.get());
                             if (st.error_code() == grpc::StatusCode::NOT_FOUND &&
                                 st.error_message().find("unknown") != std::string::npos) {
                               register_again();  // dropped meanwhile, as GetTask's answer
                               return;
                             }
                             if (!st.ok()) {
                               if (!outage(st)) {
                                 std::lock_guard lk(s_.mu);
                                 ++s_.errors;
                               }
                               retry_later();
                               return;
                             }
                             {
                               std::lock_guard lk(s_.mu);
                               ++s_.scene_fetches;
                             }
                             has_scene_ = true;
                             after_delay(tasks);
                           });
}

void SimWorker::after_delay(std::vector<v1::BandTask> tasks) {
  double ms = 0;
  for (size_t i = 0; i < tasks.size() && s_.delay_ms > 0; ++i) {
    double one = s_.delay_ms;
    if (s_.delay_sigma > 0) {
      // Log-normal with median `delay_ms`: real band times are skewed.
      std::lognormal_distribution<double> d(std::log(one), s_.delay_sigma);
      one = d(rng_);
    }
    ms += one;
  }
  if (behaviour_ == Behaviour::kLate) ms = static_cast<double>(lease_ms_) + 500;
  if (ms <= 0) {
    complete(tasks);
    return;
  }
  s_.timers->at(Clock::now() + std::chrono::microseconds(static_cast<int64_t>(ms * 1000)),
                [this, tasks = std::move(tasks)] { complete(tasks); });
}

void SimWorker::complete(const std::vector<v1::BandTask>& tasks) {
  if (s_.stopping) return;
  auto call = std::make_shared<Call<v1::CompleteBandRequest, v1::CompleteBandResponse>>(Ms(30000));
  for (size_t i = 0; i < tasks.size(); ++i) {
    v1::CompleteBandRequest* one = i == 0 ? &call->req : call->req.add_more();
    one->ParseFromString(*s_.payload(tasks[i]));
    one->set_lease_id(tasks[i].lease_id());
  }
  call->req.set_worker_id(id_);
  call->req.set_want_next(s_.want_next);
  call->req.set_max_next(s_.batch);
  {
    std::lock_guard lk(s_.mu);
    ++s_.complete_calls;
  }
  track(call->ctx.get());
  const auto sent = Clock::now();
  stub_->async()->CompleteBand(call->ctx.get(), &call->req, &call->resp,
                               [this, call, sent](grpc::Status st) {
                                 untrack(call->ctx.get());
                                 on_completed(*call, st, sent);
                               });
}

void SimWorker::on_completed(const Call<v1::CompleteBandRequest, v1::CompleteBandResponse>& call,
                             const grpc::Status& st, Clock::time_point sent) {
  {
    std::lock_guard lk(mu_);
    leases_.clear();
  }
  if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
    // The worker was dropped while it held the band: refused, as a result
    // for a lapsed lease is.
    {
      std::lock_guard lk(s_.mu);
      s_.refused += 1 + call.req.more_size();
    }
    register_again();
    return;
  }
  const bool away = !st.ok() && outage(st);
  {
    std::lock_guard lk(s_.mu);
    if (away) {
      // The coordinator went away with the band: its lease is void, the
      // band is rendered again.
    } else if (!st.ok()) {
      ++s_.errors;
      if (s_.errors <= 5)
        std::fprintf(stderr, "worker %d: CompleteBand: %s\n", index_, st.error_message().c_str());
    } else {
      // Each result of the call is judged alone (CompleteBandResponse.more).
      const int accepted = (call.resp.accepted() ? 1 : 0) +
                           static_cast<int>(std::count_if(
                               call.resp.more().begin(), call.resp.more().end(),
                               [](const v1::CompleteBandResponse& m) { return m.accepted(); }));
      s_.accepted += accepted;
      s_.refused += 1 + call.req.more_size() - accepted;
      if (accepted > 0) {
        s_.completion_ms.push_back(seconds_since(sent) * 1000);
        const auto now = Clock::now();
        if (s_.first_accept == Clock::time_point{}) s_.first_accept = now;
        s_.last_accept = now;
      }
    }
  }
  if (st.ok() && call.resp.has_next()) {
    {
      std::lock_guard lk(s_.mu);
      if (call.resp.next().has_task()) s_.with_answer += 1 + call.resp.next().more_size();
    }
    on_task(call.resp.next(), grpc::Status::OK, std::nullopt);
    return;
  }
  poll();
}

}  // namespace locus::farm_scale
