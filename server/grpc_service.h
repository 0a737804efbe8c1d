// The coordinator's gRPC adapter: ClientService and WorkerService check
// each call's credentials (common/farm/auth.h) and forward to the handlers
// (server/handlers.h), counting each call's bytes (server/metrics.h).
// Lifecycle: start (bind, with TLS or explicitly insecure), serve, drain
// (SIGTERM), shutdown with a deadline, wait. The standard health service
// answers on the main port and, plaintext, on --health (proto/wire/health.h).
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "proto/wire/health.h"
#include "proto/wire/rpc.h"
#include "server/coordinator.h"
#include "server/handlers.h"
#include "server/http_api.h"
#include "server/http_server.h"

namespace locus::rpc {

class CoordinatorServer {
 public:
  explicit CoordinatorServer(farm::Coordinator& coordinator);
  ~CoordinatorServer();

  // Binds `address` ("127.0.0.1:0" picks a free port) and serves; returns
  // the bound port. Refuses what check_server_security() refuses.
  Result<int> start(const std::string& address, ServerSecurity security);
  // The health service alone on a plaintext port of its own (--health),
  // for probes; returns the bound port.
  Result<int> serve_health(const std::string& address);
  // The dashboard and its JSON API on a port of their own (--http), after
  // start(): the same tokens and handlers, and TLS with the main port's
  // certificate when it has one. Returns the bound port.
  Result<int> serve_http(HttpServerOptions options, HttpOptions api = {});
  // SIGTERM: not ready (health), no new jobs or leases, waits up to
  // `max` for the bands in flight (Coordinator::drain()), then shutdown().
  void drain(farm::Millis max, farm::Millis grace);
  // Not ready; ends long polls and watches; refuses new calls, gives
  // running ones until `grace` to finish, then cancels them; then shuts
  // the coordinator down (frames written, store closed).
  void shutdown(farm::Millis grace);
  void wait();

 private:
  class ClientImpl;
  class WorkerImpl;
  farm::Coordinator& coordinator_;
  Handlers handlers_;
  farm::Authenticator auth_;
  std::unique_ptr<ClientImpl> client_;
  std::unique_ptr<WorkerImpl> worker_;
  HealthService health_service_;  // on the main port
  std::unique_ptr<grpc::Server> server_;
  HealthServer health_;  // --health
  std::string tls_cert_, tls_key_;  // the main port's, for --http
  std::unique_ptr<HttpApi> http_api_;
  std::unique_ptr<HttpServer> http_;
};

}  // namespace locus::rpc
