// The standard gRPC health service (grpc.health.v1, proto/health.proto),
// for Kubernetes' grpc probes, Docker's HEALTHCHECK and `locus health`.
// Each process serves it on a port of its own (--health ADDR), plaintext
// and without tokens: probes speak plaintext, and the answer says only
// whether the process serves; the coordinator answers on its main port too.
// Two service names:
//   ""          readiness: the coordinator serves and is not draining; the
//               worker is registered with its coordinator and not stopping;
//   "liveness"  the process runs (NOT_SERVING only as it exits).
// docs/deploy.md "Health".
#pragma once

#include <grpcpp/grpcpp.h>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "common/base/status.h"
#include "common/farm/auth.h"
#include "common/farm/types.h"
#include "proto/health.grpc.pb.h"

namespace locus::rpc {

inline constexpr char kLivenessService[] = "liveness";

// Check and Watch over the two names; not ready until set_ready(true).
class HealthService final : public grpc::health::v1::Health::Service {
 public:
  void set_ready(bool ready);
  // Both names NOT_SERVING for good; watches end.
  void shutdown();

  grpc::Status Check(grpc::ServerContext* ctx, const grpc::health::v1::HealthCheckRequest* req,
                     grpc::health::v1::HealthCheckResponse* resp) override;
  // The status now, then each change, until the client goes or shutdown().
  grpc::Status Watch(grpc::ServerContext* ctx, const grpc::health::v1::HealthCheckRequest* req,
                     grpc::ServerWriter<grpc::health::v1::HealthCheckResponse>* writer) override;

 private:
  using Serving = grpc::health::v1::HealthCheckResponse::ServingStatus;
  // mu_ held; SERVICE_UNKNOWN for other names.
  Serving status(const std::string& service) const;

  std::mutex mu_;
  std::condition_variable changed_;
  bool ready_ = false;
  bool exiting_ = false;
  uint64_t version_ = 0;
};

// The health service alone, on a plaintext port of its own.
class HealthServer {
 public:
  HealthServer() = default;
  ~HealthServer();
  HealthServer(const HealthServer&) = delete;
  HealthServer& operator=(const HealthServer&) = delete;

  // Binds `address` (HOST:PORT; port 0: any free port); returns the port.
  Result<int> start(const std::string& address);
  void set_ready(bool ready) { service_.set_ready(ready); }
  // NOT_SERVING for both names, then stops.
  void shutdown();

 private:
  HealthService service_;
  std::unique_ptr<grpc::Server> server_;
};

// One Check call to `address` for `service`: whether it is SERVING.
// Plaintext, unless the credentials name a CA (the coordinator's main,
// TLS port). Unavailable when nothing answers, NotFound for a name the
// service does not know.
Result<bool> check_health(const std::string& address, const std::string& service,
                          const farm::Credentials& credentials, farm::Millis timeout);

}  // namespace locus::rpc
