// The coordinator's gRPC adapter: ClientService and WorkerService forward to
// farm::Coordinator, converting with rpc.h. Lifecycle: start (bind), serve,
// shutdown with a deadline, wait.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "server/coordinator.h"

namespace locus::rpc {

class CoordinatorServer {
 public:
  explicit CoordinatorServer(farm::Coordinator& coordinator);
  ~CoordinatorServer();

  // Binds `address` ("127.0.0.1:0" picks a free port) and serves; returns
  // the bound port.
  Result<int> start(const std::string& address);
  // Refuses new calls, gives running ones until `grace` to finish, then
  // cancels them.
  void shutdown(farm::Millis grace);
  void wait();

 private:
  class ClientImpl;
  class WorkerImpl;
  farm::Coordinator& coordinator_;
  std::unique_ptr<ClientImpl> client_;
  std::unique_ptr<WorkerImpl> worker_;
  std::unique_ptr<grpc::Server> server_;
};

}  // namespace locus::rpc
