#include "common/base/parallel.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "common/base/log.h"

namespace locus {

int render_threads(const RenderParams& params) {
  if (params.threads > 0) return params.threads;
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

void parallel_for(int n, int threads, FunctionRef<void(int)> body) {
  threads = std::clamp(threads, 1, std::max(1, n));
  if (threads == 1) {
    for (int i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::mutex mu;
  std::exception_ptr error;
  auto work = [&] {
    try {
      for (int i = next++; i < n && !failed.load(std::memory_order_relaxed); i = next++) body(i);
    } catch (...) {
      std::lock_guard<std::mutex> lock(mu);
      if (!error) error = std::current_exception();
      failed.store(true, std::memory_order_relaxed);
    }
  };
  // The pool logs under the caller's band ids, as render_band's does.
  const BandLogIds log_ids = current_band_log_ids();
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) {
    pool.emplace_back([&] {
      BandLogScope scope(log_ids);
      work();
    });
  }
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

int chunk_count(int n, int grain, int most) {
  return std::clamp(n / std::max(1, grain), 1, std::max(1, most));
}

void parallel_chunks(int n, int threads, int grain, FunctionRef<void(int, int)> body) {
  if (n <= 0) return;
  const int chunks = chunk_count(n, grain, 4 * std::max(1, threads));
  parallel_for(chunks, threads,
               [&](int c) { body(chunk_edge(n, c, chunks), chunk_edge(n, c + 1, chunks)); });
}

}  // namespace locus
