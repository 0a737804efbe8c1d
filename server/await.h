// A call that answers through a callback (the coordinator's asynchronous
// calls: Coordinator::complete_band_async, Handlers::StartCompleteBand),
// waited for by a caller with a thread to spare (tests, the fuzzer, tools).
#pragma once

#include <condition_variable>
#include <mutex>
#include <optional>
#include <utility>

namespace locus {

// Runs `start(done)`, where `done(value)` is called exactly once, on any
// thread, perhaps before `start` returns; returns that value.
template <typename T, typename Start>
T await_answer(Start&& start) {
  struct Answer {
    std::mutex mu;
    std::condition_variable cv;
    std::optional<T> value;
  };
  Answer answer;
  start([&answer](T value) {
    std::lock_guard lk(answer.mu);
    answer.value.emplace(std::move(value));
    answer.cv.notify_all();
  });
  std::unique_lock lk(answer.mu);
  answer.cv.wait(lk, [&] { return answer.value.has_value(); });
  return std::move(*answer.value);
}

}  // namespace locus
