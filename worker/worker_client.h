// The worker's gRPC side: registers with the coordinator, long-polls for
// bands, fetches each scene once, renders through BandRenderer, returns the
// pixels under the band's lease and heartbeats meanwhile. Stateless: a
// killed worker loses only the band in hand, which the coordinator leases
// again when this worker's lease lapses.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "common/farm/auth.h"
#include "common/farm/types.h"

namespace locus::farm {

struct WorkerOptions {
  std::string coordinator;        // HOST:PORT
  Credentials credentials;        // token, TLS files, --insecure
  std::string mesh_root;          // OBJ files a scene may name; empty: meshes inline only
  int threads = 1;                // per band
  std::string name;               // default host:pid
  std::vector<std::string> tags;  // pools (`--tag`): jobs that require them come here only
  Millis poll{10000};             // long-poll wait per GetTask
  // Test only (tests/faults/run.sh): wait this long before rendering each
  // band, to play a slow worker.
  Millis slow_band{0};
  // A render that has not returned this long after its band was revoked
  // (it ignores the cancellation: a wedged library call) makes the worker
  // exit, so that its supervisor restarts it instead of it wedging silently.
  Millis abandon_grace{60000};
  // What "exit" is: null logs and calls std::_Exit(3); tests replace it.
  std::function<void()> on_wedged;
  // Called when the worker becomes ready (registered, and its last call
  // reached the coordinator) or stops being ready: the health service's
  // readiness. From the worker's threads.
  std::function<void(bool ready)> on_ready;
};

class WorkerMetrics;

class WorkerClient {
 public:
  explicit WorkerClient(WorkerOptions options);
  ~WorkerClient();

  // Serves until stop() (then finishes and returns the band in hand, or
  // hands it back if it has not started rendering it). Returns 0; 1 when
  // the credentials are unusable or the coordinator refuses them
  // (UNAUTHENTICATED, PERMISSION_DENIED): retrying would not help.
  int run();
  // Safe from any thread (a signal-handling one).
  void stop();
  // Gives the band in hand back to the coordinator at once (not counted as
  // a failed attempt), for a worker that must exit now: render_band() cannot
  // be interrupted, so the caller exits the process right after.
  void hand_back();

  // The worker's Prometheus series (worker/worker_metrics.h).
  WorkerMetrics& metrics();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace locus::farm
