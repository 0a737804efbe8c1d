// The coordinator's gRPC adapter: ClientService and WorkerService check
// each call's credentials (server/auth.h) and forward to the handlers
// (server/handlers.h). Lifecycle: start (bind, with TLS or explicitly
// insecure), serve, shutdown with a deadline, wait.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "server/coordinator.h"
#include "server/handlers.h"
#include "server/rpc.h"

namespace locus::rpc {

class CoordinatorServer {
 public:
  explicit CoordinatorServer(farm::Coordinator& coordinator);
  ~CoordinatorServer();

  // Binds `address` ("127.0.0.1:0" picks a free port) and serves; returns
  // the bound port. Refuses what check_server_security() refuses.
  Result<int> start(const std::string& address, ServerSecurity security);
  // Refuses new calls, gives running ones until `grace` to finish, then
  // cancels them.
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
  std::unique_ptr<grpc::Server> server_;
};

}  // namespace locus::rpc
