#include "server/handler_pool.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>

namespace locus::rpc {

HandlerPool::HandlerPool(int threads) {
  if (threads == 0) {
    threads = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 4, 32);
  }
  if (threads < 0) return;  // none: post() runs the work where it is called
  threads_.reserve(static_cast<size_t>(threads));
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { run(); });
}

HandlerPool::~HandlerPool() {
  {
    std::lock_guard lk(mu_);
    stopping_ = true;
  }
  ready_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void HandlerPool::post(std::function<void()> fn, bool urgent) {
  if (threads_.empty()) {
    fn();
    return;
  }
  {
    std::lock_guard lk(mu_);
    (urgent ? urgent_ : normal_).push_back(std::move(fn));
  }
  ready_.notify_one();
}

void HandlerPool::run() {
  std::unique_lock lk(mu_);
  for (;;) {
    ready_.wait(lk, [&] { return stopping_ || !urgent_.empty() || !normal_.empty(); });
    auto& queue = !urgent_.empty() ? urgent_ : normal_;
    if (queue.empty()) return;  // stopping, and nothing left
    std::function<void()> fn = std::move(queue.front());
    queue.pop_front();
    lk.unlock();
    // The handlers answer their call whatever happens (grpc_service.cpp);
    // nothing may end this thread.
    try {
      fn();
    } catch (const std::exception& e) {
      spdlog::error("handler: {}", e.what());
    }
    lk.lock();
  }
}

}  // namespace locus::rpc
