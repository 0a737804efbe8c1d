#include "proto/wire/health.h"

#include <chrono>

#include "proto/wire/rpc.h"

namespace locus::rpc {

using grpc::health::v1::HealthCheckRequest;
using grpc::health::v1::HealthCheckResponse;

void HealthService::set_ready(bool ready) {
  {
    std::lock_guard lk(mu_);
    if (ready_ == ready) return;
    ready_ = ready;
    ++version_;
  }
  changed_.notify_all();
}

void HealthService::shutdown() {
  {
    std::lock_guard lk(mu_);
    exiting_ = true;
    ++version_;
  }
  changed_.notify_all();
}

HealthService::Serving HealthService::status(const std::string& service) const {
  if (service.empty()) {
    return ready_ && !exiting_ ? HealthCheckResponse::SERVING : HealthCheckResponse::NOT_SERVING;
  }
  if (service == kLivenessService) {
    return exiting_ ? HealthCheckResponse::NOT_SERVING : HealthCheckResponse::SERVING;
  }
  return HealthCheckResponse::SERVICE_UNKNOWN;
}

grpc::Status HealthService::Check(grpc::ServerContext*, const HealthCheckRequest* req,
                                  HealthCheckResponse* resp) {
  std::lock_guard lk(mu_);
  const Serving s = status(req->service());
  // The protocol: an unknown name is NOT_FOUND for Check.
  if (s == HealthCheckResponse::SERVICE_UNKNOWN) {
    return grpc::Status(grpc::StatusCode::NOT_FOUND,
                        "unknown service '" + req->service() + "' (\"\" or \"liveness\")");
  }
  resp->set_status(s);
  return grpc::Status::OK;
}

grpc::Status HealthService::Watch(grpc::ServerContext* ctx, const HealthCheckRequest* req,
                                  grpc::ServerWriter<HealthCheckResponse>* writer) {
  std::unique_lock lk(mu_);
  for (;;) {
    const uint64_t seen = version_;
    HealthCheckResponse resp;
    resp.set_status(status(req->service()));
    const bool last = exiting_;
    lk.unlock();
    if (!writer->Write(resp) || last) return grpc::Status::OK;
    lk.lock();
    // Wake now and then to notice a client that went away.
    while (version_ == seen && !ctx->IsCancelled()) changed_.wait_for(lk, std::chrono::seconds(1));
    if (ctx->IsCancelled()) return grpc::Status::CANCELLED;
  }
}

HealthServer::~HealthServer() { shutdown(); }

Result<int> HealthServer::start(const std::string& address) {
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(address, grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service_);
  // Anyone who reaches the port may ask: a port of its own (not shared
  // through SO_REUSEPORT), small messages, few threads (a Watch holds one).
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.SetMaxReceiveMessageSize(4096);
  grpc::ResourceQuota quota("locus-health");
  quota.SetMaxThreads(16);
  builder.SetResourceQuota(quota);
  server_ = builder.BuildAndStart();
  if (!server_ || port == 0) {
    server_.reset();
    return Status(Code::kUnavailable,
                  "--health " + address + ": cannot listen (address in use, or not local?)");
  }
  return port;
}

void HealthServer::shutdown() {
  service_.shutdown();
  if (!server_) return;
  server_->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
  server_->Wait();
  server_.reset();
}

Result<bool> check_health(const std::string& address, const std::string& service,
                          const farm::Credentials& credentials, farm::Millis timeout) {
  std::shared_ptr<grpc::Channel> channel;
  if (credentials.tls_ca.empty()) {
    channel = grpc::CreateChannel(address, grpc::InsecureChannelCredentials());
  } else {
    auto c = connect(address, credentials);
    if (!c.ok()) return c.status();
    channel = c->channel;
  }
  auto stub = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + timeout);
  HealthCheckRequest req;
  req.set_service(service);
  HealthCheckResponse resp;
  const grpc::Status st = stub->Check(&ctx, req, &resp);
  if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
    return NotFound("the health service at " + address + " knows no service '" + service +
                    "' (\"\" for readiness, or \"liveness\")");
  }
  if (!st.ok()) return FromGrpc(st, "health service at " + address);
  return resp.status() == HealthCheckResponse::SERVING;
}

}  // namespace locus::rpc
