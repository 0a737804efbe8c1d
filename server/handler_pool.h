// The threads that run the worker service's handlers (grpc_service.cpp).
// gRPC 1.51 runs callback-API handlers on its own few threads (two on a
// 2-core machine); a handler that waits there for the coordinator's lock
// (held by the group commit's transaction, the dispatch thread, the frame
// writer) holds up every other call of every worker, heartbeats and
// registrations included, and the connections being set up. Handed over
// to this pool instead, gRPC's threads only take calls in and send
// answers out (docs/farm.md "Under load"). Urgent work (heartbeats,
// registrations, scenes: small and late-sensitive) runs before queued
// results and polls.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace locus::rpc {

class HandlerPool {
 public:
  // `threads` 0: one per core, at least 4 (they mostly wait for the
  // coordinator's lock), at most 32; negative: none, post() runs the
  // work on the caller's thread (--handler-threads -1).
  explicit HandlerPool(int threads = 0);
  // Runs everything queued, then joins.
  ~HandlerPool();
  HandlerPool(const HandlerPool&) = delete;
  HandlerPool& operator=(const HandlerPool&) = delete;

  void post(std::function<void()> fn, bool urgent = false);
  int threads() const { return static_cast<int>(threads_.size()); }

 private:
  void run();
  std::mutex mu_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> urgent_, normal_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace locus::rpc
