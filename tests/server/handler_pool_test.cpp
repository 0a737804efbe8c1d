// The worker service's handler threads (server/handler_pool.h), and the
// coordinator counting a worker's call as heard the moment it arrives
// (Coordinator::worker_call_arrived), however long it then waits for a
// handler: a busy coordinator drops no worker that is talking to it.
#include "server/handler_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "server/coordinator.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::rpc {
namespace {

// A gate the first task waits at, so that the others queue behind it.
struct Gate {
  std::mutex mu;
  std::condition_variable cv;
  bool open = false;
  void wait() {
    std::unique_lock lk(mu);
    cv.wait(lk, [&] { return open; });
  }
  void release() {
    {
      std::lock_guard lk(mu);
      open = true;
    }
    cv.notify_all();
  }
};

TEST(HandlerPool, UrgentWorkGoesBeforeQueuedWorkAndEverythingQueuedRuns) {
  Gate gate;
  std::mutex mu;
  std::vector<std::string> order;
  const auto note = [&](const char* what) {
    return [&, what] {
      std::lock_guard lk(mu);
      order.emplace_back(what);
    };
  };
  {
    HandlerPool pool(1);
    EXPECT_EQ(pool.threads(), 1);
    std::atomic<bool> started{false};
    pool.post([&] {
      started = true;
      gate.wait();
    });
    while (!started) std::this_thread::yield();
    pool.post(note("result 1"));
    pool.post(note("heartbeat 1"), true);
    pool.post(note("result 2"));
    pool.post(note("heartbeat 2"), true);
    gate.release();
  }  // the destructor runs what is queued, then joins
  EXPECT_EQ(order,
            (std::vector<std::string>{"heartbeat 1", "heartbeat 2", "result 1", "result 2"}));
}

TEST(HandlerPool, AnExceptionEndsItsTaskNotTheThread) {
  std::atomic<int> ran{0};
  {
    HandlerPool pool(1);
    pool.post([] { throw std::runtime_error("a handler's bad_alloc"); });
    pool.post([&] { ++ran; });
  }
  EXPECT_EQ(ran.load(), 1);
}

TEST(HandlerPool, DefaultsToOnePerCoreAtLeastFourAndNoneRunsInPlace) {
  {
    HandlerPool pool;
    EXPECT_GE(pool.threads(), 4);
    EXPECT_LE(pool.threads(), 32);
  }
  HandlerPool none(-1);  // --handler-threads -1: gRPC's threads answer
  EXPECT_EQ(none.threads(), 0);
  std::thread::id where;
  none.post([&] { where = std::this_thread::get_id(); });
  EXPECT_EQ(where, std::this_thread::get_id());
}

TEST(HandlerPool, AWorkersCallCountsAsHeardWhenItArrives) {
  farm::test_doubles::TempDir dir;
  farm::CoordinatorOptions o;
  o.data_dir = (dir.path / "data").string();
  o.fsync = false;
  o.lease = farm::Millis(300);
  o.tick = farm::Millis(10);
  farm::Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  auto talking = c.register_worker("talking", 1);
  auto silent = c.register_worker("silent", 1);
  ASSERT_TRUE(talking.ok() && silent.ok());
  // Six lease times of calls that arrive but that no handler has reached
  // (only worker_call_arrived): the talking worker stays, the silent one
  // is dropped.
  for (int i = 0; i < 36; ++i) {
    c.worker_call_arrived(talking->worker_id);
    std::this_thread::sleep_for(farm::Millis(50));
  }
  std::vector<std::string> names;
  for (const farm::WorkerInfo& w : c.workers()) names.push_back(w.name);
  EXPECT_EQ(names, std::vector<std::string>{"talking"});
  // An id no worker has is ignored.
  c.worker_call_arrived("w-none");
  c.worker_call_arrived("");
  c.shutdown();
}

}  // namespace
}  // namespace locus::rpc
