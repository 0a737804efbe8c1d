// The simulated workers of locus-farm-scale (bench/farm/scale.cpp): what
// they share (the farm's address, the reference frame, the run's settings
// and counts) and `SimWorker`, one worker as a real gRPC client of the
// coordinator on a connection of its own, through gRPC's callback API, so
// that a thousand of them need no thousand threads. It registers, long-polls
// GetTask, fetches the scene once, heartbeats while it holds a band and
// returns the band after a delay, or misbehaves as its `Behaviour` says.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "bench/farm/scale_probe.h"
#include "proto/locus.grpc.pb.h"

namespace locus::farm_scale {

using Ms = std::chrono::milliseconds;

// ---------------------------------------------------------------- the workers

enum class Behaviour { kNormal, kDie, kStall, kLate };

struct Shared {
  std::string address;
  v1::Scene scene;           // what GetScene would return (fetched once per worker all the same)
  std::vector<float> frame;  // the reference frame, linear RGB
  int width = 0;
  Timers* timers = nullptr;
  double delay_ms = 0;
  double delay_sigma = 0;   // log-normal spread of the delay; 0: fixed
  bool want_next = true;    // CompleteBandRequest.want_next (--no-next: GetTask for each band)
  bool png_deflate = true;  // RegisterRequest.encodings (--no-png-deflate: rgb8+zstd)
  int batch = 1;            // bands per call (GetTaskRequest.max_bands, CompleteBandRequest.more)
  int revive_ms = 0;        // a dying worker comes back after this long (0: never)
  bool outage_ok = false;   // the coordinator restarts during the run (a soak)
  std::atomic<bool> stopping{false};

  std::mutex mu;
  std::vector<double> dispatch_ms;    // GetTask sent to a band in hand
  std::vector<double> completion_ms;  // CompleteBand sent to its answer
  std::map<std::tuple<int, int, int>, std::shared_ptr<const std::string>>
      payloads;  // by rows, encoding
  int64_t accepted = 0, refused = 0, errors = 0, scene_fetches = 0, heartbeats = 0,
          registrations = 0;
  int64_t get_tasks = 0;       // GetTask calls
  int64_t outage_errors = 0;   // calls failed while the coordinator was away (--outage-ok)
  int64_t revived = 0;         // dead workers come back (--revive-ms)
  int64_t with_answer = 0;     // bands leased with a CompleteBand's answer
  int64_t complete_calls = 0;  // CompleteBand calls (several results each with --batch)
  Clock::time_point first_accept{}, last_accept{};

  // The CompleteBandRequest's pixels for rows [y0, y1), in the encoding
  // the band was leased with (BandTask.encoding), as locus-worker sends
  // them (worker/band_renderer.cpp); serialized once.
  std::shared_ptr<const std::string> payload(const v1::BandTask& task);
};

class SimWorker {
 public:
  SimWorker(Shared& shared, int index, Behaviour behaviour);

  // A connection of its own, as a worker on its own host has.
  void connect();

  // Registers (blocking: done for all workers before the clock starts).
  bool start();

  void poll();

  // Heartbeats the band in hand, if any (the timer thread, every second).
  void heartbeat();

  // Ends every call in flight (the run is over).
  void stop();

  size_t in_flight();

 private:
  template <typename Req, typename Resp>
  struct Call {
    explicit Call(Ms deadline) : ctx(std::make_unique<grpc::ClientContext>()) {
      ctx->set_deadline(std::chrono::system_clock::now() + deadline);
    }
    std::unique_ptr<grpc::ClientContext> ctx;
    Req req;
    Resp resp;
  };

  void track(grpc::ClientContext* c);
  void untrack(grpc::ClientContext* c);

  void retry_later();

  v1::RegisterRequest registration() const;
  void registered(const v1::RegisterResponse& resp);

  // Dropped by the coordinator (silent past its lease: a late worker):
  // register again and go on, as locus-worker does. Asynchronous: the
  // timer thread, which sends every worker's heartbeats, never waits for
  // the coordinator.
  void register_again();
  void register_again_later();

  // A call that failed because the coordinator is away (restarting), in a
  // run that expects it: counted apart, not as an error.
  bool outage(const grpc::Status& st);

  // A GetTask's answer, or (no `sent`) the one that came with a
  // CompleteBand's (CompleteBandResponse.next).
  void on_task(const v1::GetTaskResponse& resp, const grpc::Status& st,
               std::optional<Clock::time_point> sent);

  // The scene once per worker, as a real one fetches it once per hash.
  void fetch_scene(std::vector<v1::BandTask> tasks);

  // The bands rendered one after the other: the sum of their times.
  void after_delay(std::vector<v1::BandTask> tasks);

  // Every band in hand in one call: the first as the request, the others
  // in its `more`.
  void complete(const std::vector<v1::BandTask>& tasks);

  void on_completed(const Call<v1::CompleteBandRequest, v1::CompleteBandResponse>& call,
                    const grpc::Status& st, Clock::time_point sent);

  Shared& s_;
  const int index_;
  const Behaviour behaviour_;
  std::mt19937 rng_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  std::mutex mu_;
  std::string id_;
  int lease_ms_ = 5000;
  std::vector<std::string> leases_;  // the bands in hand
  std::vector<grpc::ClientContext*> in_flight_;
  std::atomic<bool> dead_{false};
  bool has_scene_ = false;  // touched by this worker's own callbacks only, one at a time
};

}  // namespace locus::farm_scale
