// The cost pre-pass of a submission (CoordinatorOptions::cost_pass, the
// band edges of common/farm/band_split.h) runs outside the coordinator's
// lock: a big scene's takes seconds, and the farm's other calls (leases,
// results, status) are answered meanwhile. The submission is admitted
// again after it. No network: a Coordinator, a worker played by the test,
// and a cost pass that waits until the test lets it go.
#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <future>
#include <mutex>

#include "server/coordinator.h"
#include "tests/farm_fixture.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {

// A cost pass held at its start until release(); its edges are fixed.
struct HeldCostPass {
  std::mutex mu;
  std::condition_variable cv;
  bool entered = false, released = false;
  const std::vector<int> edges{0, 3, 16};

  std::vector<int> run(const CheckedSubmission&, std::vector<float>*) {
    std::unique_lock lk(mu);
    entered = true;
    cv.notify_all();
    cv.wait(lk, [&] { return released; });
    return edges;
  }
  bool wait_entered() {
    std::unique_lock lk(mu);
    return cv.wait_for(lk, std::chrono::seconds(60), [&] { return entered; });
  }
  void release() {
    std::lock_guard lk(mu);
    released = true;
    cv.notify_all();
  }
};

// Runs `call` on another thread: true when it returned within a minute.
// Should it hang (the lock held across the pass), the pass is released so
// that the test fails instead of hanging.
template <typename F>
bool answered_meanwhile(HeldCostPass& pass, F call) {
  auto f = std::async(std::launch::async, call);
  if (f.wait_for(std::chrono::seconds(60)) == std::future_status::ready) return f.get();
  pass.release();
  f.wait();
  return false;
}

TEST(CostPass, TheFarmIsAnsweredWhileASubmissionsPassRuns) {
  test_doubles::TempDir dir;
  CoordinatorOptions o = test_doubles::test_options(dir.path);
  HeldCostPass pass;
  bool first = true;
  // The first job's pass is immediate; the second's is held.
  o.cost_pass = [&](const CheckedSubmission& job, std::vector<float>* costs) {
    if (first) {
      first = false;
      return std::vector<int>{};
    }
    return pass.run(job, costs);
  };
  Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  auto a = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 16, 1, 1, 2, "a_####.png"));
  ASSERT_TRUE(a.ok()) << a.status().message();
  test_doubles::TestWorker w(c, "w:1");
  auto lease = w.take();
  ASSERT_TRUE(lease.has_value());

  auto b = std::async(std::launch::async, [&] {
    return c.submit(testing_farm::request(testing_farm::kSpheres, 16, 16, 1, 1, 2, "b_####.png"));
  });
  ASSERT_TRUE(pass.wait_entered());
  // While job b's pass runs: a result is accepted, the next band leased,
  // and the farm's status read.
  EXPECT_TRUE(answered_meanwhile(pass, [&] { return w.complete(*lease); }));
  EXPECT_TRUE(answered_meanwhile(pass, [&] { return w.take().has_value(); }));
  EXPECT_TRUE(answered_meanwhile(pass, [&] { return c.jobs().size() == 1; }));
  pass.release();
  auto job = b.get();
  ASSERT_TRUE(job.ok()) << job.status().message();
  EXPECT_EQ(job->spec.band_edges, pass.edges);
  EXPECT_EQ(c.jobs().size(), 2u);
  c.shutdown();
}

TEST(CostPass, ASubmissionIsAdmittedAgainAfterItsPass) {
  test_doubles::TempDir dir;
  CoordinatorOptions o = test_doubles::test_options(dir.path);
  HeldCostPass pass;
  o.cost_pass = [&](const CheckedSubmission& job, std::vector<float>* costs) {
    return pass.run(job, costs);
  };
  Coordinator c(o);
  ASSERT_TRUE(c.start().ok());
  auto b = std::async(std::launch::async, [&] {
    return c.submit(testing_farm::request(testing_farm::kSpheres, 16, 16, 1, 1, 2, "b_####.png"));
  });
  ASSERT_TRUE(pass.wait_entered());
  // A drain begun during the pass: the job is refused, and not recorded.
  c.drain();
  pass.release();
  auto job = b.get();
  ASSERT_FALSE(job.ok());
  EXPECT_EQ(job.status().code(), Code::kUnavailable) << job.status().message();
  EXPECT_NE(job.status().message().find("shutting down"), std::string::npos)
      << job.status().message();
  EXPECT_TRUE(c.jobs().empty());
  c.shutdown();
}

// With many bands per worker the pre-pass is not run and the bands are
// of equal height (cost_split_pays), unless the coordinator is told to
// run it always (--always-cost-bands).
TEST(CostPass, ManyBandsPerWorkerGetEqualHeightsUnlessAlwaysAskedFor) {
  for (const bool always : {false, true}) {
    test_doubles::TempDir dir;
    CoordinatorOptions o = test_doubles::test_options(dir.path);
    o.always_cost_bands = always;
    int passes = 0;
    o.cost_pass = [&](const CheckedSubmission& job, std::vector<float>* costs) {
      ++passes;
      return cost_band_edges(job, costs);
    };
    Coordinator c(o);
    ASSERT_TRUE(c.start().ok());
    test_doubles::TestWorker w(c, "w:1");
    // One worker: 4 bands get the pre-pass, 8 do not (unless always).
    auto few = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 16, 1, 1, 4, "f_####.png"));
    ASSERT_TRUE(few.ok()) << few.status().message();
    EXPECT_EQ(few->spec.band_edges.size(), 5u);
    EXPECT_EQ(few->spec.row_costs.size(), 16u);
    auto many = c.submit(testing_farm::request(testing_farm::kSpheres, 16, 16, 1, 1, 8, "m_####.png"));
    ASSERT_TRUE(many.ok()) << many.status().message();
    EXPECT_EQ(many->spec.band_edges.size(), always ? 9u : 0u) << "always " << always;
    EXPECT_EQ(many->spec.row_costs.size(), always ? 16u : 0u);
    EXPECT_EQ(passes, always ? 2 : 1);
    c.shutdown();
  }
}

}  // namespace
}  // namespace locus::farm
