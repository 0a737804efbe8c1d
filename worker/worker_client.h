// The worker's gRPC side: registers with the coordinator, long-polls for
// bands, fetches each scene once, renders through BandRenderer, returns the
// pixels under the band's lease and heartbeats meanwhile. Stateless: a
// killed worker loses only the band in hand, which the coordinator leases
// again when this worker's lease lapses.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "server/auth.h"
#include "server/farm_types.h"

namespace locus::farm {

struct WorkerOptions {
  std::string coordinator;  // HOST:PORT
  Credentials credentials;  // token, TLS files, --insecure
  std::string mesh_root;    // OBJ files a scene may name; empty: meshes inline only
  int threads = 1;          // per band
  std::string name;         // default host:pid
  Millis poll{10000};       // long-poll wait per GetTask
};

class WorkerClient {
 public:
  explicit WorkerClient(WorkerOptions options);
  ~WorkerClient();

  // Serves until stop() (then finishes and returns the band in hand).
  // Returns 0; 1 when the credentials are unusable or the coordinator
  // refuses them (UNAUTHENTICATED, PERMISSION_DENIED): retrying would not
  // help.
  int run();
  // Safe from any thread (a signal-handling one).
  void stop();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace locus::farm
