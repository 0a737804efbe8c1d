// Coordinator::watch (WatchJob, `locus render`'s and `locus watch`'s wait):
// updates are throttled to one per watch_interval, but a job's end goes to
// its watchers at once, so a client waiting for its job does not wait out
// the throttle. No network: a Coordinator and a worker played by the test.
#include <gtest/gtest.h>

#include <condition_variable>
#include <future>
#include <mutex>
#include <vector>

#include "server/coordinator.h"
#include "tests/farm_fixture.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {

TEST(Watch, AJobsEndIsSentAtOnceNotAfterTheThrottle) {
  test_doubles::TempDir dir;
  CoordinatorOptions o = test_doubles::test_options(dir.path);
  // A throttle no test outlives: without the end sent at once, the watch
  // below would not return before `max`, ten minutes.
  o.watch_interval = Millis(3600 * 1000);
  o.max_watch = Millis(600 * 1000);
  Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  auto job = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 8, 1, 1, 1, "w_####.png"));
  ASSERT_TRUE(job.ok()) << job.status().message();
  std::mutex mu;
  std::condition_variable cv;
  std::vector<JobState> seen;
  auto watched = std::async(std::launch::async, [&] {
    return c.watch(job->job_id, Caller::anyone(), o.max_watch, nullptr, [&](const JobInfo& j) {
      std::lock_guard lk(mu);
      seen.push_back(j.state);
      cv.notify_all();
      return true;
    });
  });
  {
    // The first update is sent: the watch is now inside its throttle.
    std::unique_lock lk(mu);
    ASSERT_TRUE(cv.wait_for(lk, std::chrono::seconds(60), [&] { return !seen.empty(); }));
  }
  test_doubles::TestWorker w(c, "w:1");
  auto lease = w.take();
  ASSERT_TRUE(lease.has_value());
  ASSERT_TRUE(w.complete(*lease));
  if (watched.wait_for(std::chrono::seconds(120)) != std::future_status::ready) {
    c.shutdown();  // ends the watch, so that the test fails instead of hanging
    FAIL() << "the watch did not return after the job ended";
  }
  EXPECT_TRUE(watched.get().ok());
  std::lock_guard lk(mu);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), JobState::kSucceeded);
  c.shutdown();
}

}  // namespace
}  // namespace locus::farm
