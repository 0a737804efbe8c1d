// Several bands per call (GetTaskRequest.max_bands, CompleteBandRequest.more,
// issue #25 "fewer calls per band"), over loopback: a worker takes up to N
// bands in one answer, returns their results in one call and gets its next
// N with the answer; each band is leased once, each result is judged alone
// (a stale one is refused, the others accepted), a malformed one refuses
// the whole call and stores nothing, and the frames are identical to a
// single-process render.
#include "tests/farm_fixture.h"
#include "tests/wire/hand_worker.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

class BandBatchTest : public HandWorkerTest {
 protected:
  struct Leased {
    std::string job;
    HandWorker worker;
    std::vector<v1::BandTask> tasks;
  };
  // The job submitted to a started farm, and `n` of its bands leased by a
  // hand worker in one GetTask (fewer, with a test failure, when not).
  Leased submit_and_lease(const SubmitRequest& r, int n) {
    std::string job = start_with_job(r);
    HandWorker w = hand_worker();
    std::vector<v1::BandTask> tasks;
    if (!job.empty()) tasks = w.leases(n);
    EXPECT_EQ(tasks.size(), static_cast<size_t>(n));
    return {job, std::move(w), tasks};
  }
};

// One CompleteBand call holding the results of `tasks`.
v1::CompleteBandRequest batch(HandWorker& w, const std::vector<v1::BandTask>& tasks) {
  v1::CompleteBandRequest req = w.render(tasks.front(), false);
  for (size_t i = 1; i < tasks.size(); ++i) {
    v1::CompleteBandRequest more = w.render(tasks[i], false);
    more.clear_worker_id();  // a further result may leave it to the call's
    *req.add_more() = std::move(more);
  }
  return req;
}

TEST_F(BandBatchTest, BandsComeAndGoThreeToACall) {
  // 2 frames x 4 bands: 3 + 3 + 2 bands in three calls.
  const SubmitRequest r = request(kSpheres, 32, 24, 0, 1, 4, "b_#.png");
  auto [job, w, tasks] = submit_and_lease(r, 3);
  ASSERT_EQ(tasks.size(), 3u);
  std::set<std::pair<int, int>> seen;
  std::set<std::string> lease_ids;
  std::vector<size_t> sizes;
  while (!tasks.empty()) {
    sizes.push_back(tasks.size());
    for (const v1::BandTask& t : tasks) {
      EXPECT_TRUE(seen.insert({t.frame(), t.band()}).second)
          << "frame " << t.frame() << " band " << t.band() << " leased twice";
      EXPECT_TRUE(lease_ids.insert(t.lease_id()).second) << "lease " << t.lease_id() << " twice";
    }
    v1::CompleteBandRequest req = batch(w, tasks);
    req.set_want_next(true);
    req.set_max_next(3);
    v1::CompleteBandResponse resp;
    const grpc::Status st = w.send(req, &resp);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_TRUE(resp.accepted()) << resp.reason();
    ASSERT_EQ(resp.more_size(), static_cast<int>(tasks.size()) - 1);
    for (const v1::CompleteBandResponse& m : resp.more()) EXPECT_TRUE(m.accepted()) << m.reason();
    ASSERT_TRUE(resp.has_next());
    tasks = HandWorker::tasks(resp.next());
  }
  EXPECT_EQ(sizes, (std::vector<size_t>{3, 3, 2}));
  EXPECT_EQ(seen.size(), 8u);
  EXPECT_TRUE(succeeded(job, r));
}

TEST_F(BandBatchTest, AStaleResultIsRefusedAloneAndTheOthersAccepted) {
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 3, "s.png");
  auto [job, w, tasks] = submit_and_lease(r, 3);
  ASSERT_EQ(tasks.size(), 3u);
  v1::CompleteBandRequest req = batch(w, tasks);
  // A result for a lease the coordinator never gave, between two good ones.
  v1::CompleteBandRequest stale = req.more(0);
  stale.set_lease_id("l-not-a-lease");
  *req.add_more() = stale;
  std::swap(*req.mutable_more(1), *req.mutable_more(2));  // good, stale, good
  v1::CompleteBandResponse resp;
  const grpc::Status st = w.send(req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  ASSERT_EQ(resp.more_size(), 3);
  EXPECT_TRUE(resp.accepted()) << resp.reason();
  EXPECT_TRUE(resp.more(0).accepted()) << resp.more(0).reason();
  EXPECT_FALSE(resp.more(1).accepted());
  EXPECT_FALSE(resp.more(1).reason().empty());
  EXPECT_TRUE(resp.more(2).accepted()) << resp.more(2).reason();
  EXPECT_TRUE(succeeded(job, r));
}

TEST_F(BandBatchTest, AMalformedResultRefusesTheCallAndStoresNone) {
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 2, "m.png");
  auto [job, w, tasks] = submit_and_lease(r, 2);
  ASSERT_EQ(tasks.size(), 2u);
  const v1::CompleteBandRequest good = batch(w, tasks);

  struct Bad {
    const char* what;
    std::function<void(v1::CompleteBandRequest&)> spoil;
    const char* names;  // what the error must name
  };
  const std::vector<Bad> bads = {
      {"another worker's id", [](auto& q) { q.mutable_more(0)->set_worker_id("w-other"); },
       "more[0]"},
      {"no lease id", [](auto& q) { q.mutable_more(0)->clear_lease_id(); }, "more[0]"},
      {"a further result with more of its own",
       [](auto& q) { *q.mutable_more(0)->add_more() = q.more(0); }, "more[0]"},
      {"a further result asking for the next band",
       [](auto& q) { q.mutable_more(0)->set_want_next(true); }, "more[0]"},
      {"64 further results",
       [](auto& q) {
         while (q.more_size() < 64) *q.add_more() = q.more(0);
       },
       "at most 63"},
  };
  for (const Bad& bad : bads) {
    v1::CompleteBandRequest req = good;
    bad.spoil(req);
    v1::CompleteBandResponse resp;
    const grpc::Status st = w.send(req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad.what;
    EXPECT_NE(st.error_message().find(bad.names), std::string::npos)
        << bad.what << ": " << st.error_message();
  }
  // Nothing of the refused calls was stored: both leases are still open,
  // and the good call is accepted whole.
  v1::CompleteBandResponse resp;
  ASSERT_TRUE(w.send(good, &resp).ok());
  EXPECT_TRUE(resp.accepted()) << resp.reason();
  ASSERT_EQ(resp.more_size(), 1);
  EXPECT_TRUE(resp.more(0).accepted()) << resp.more(0).reason();
  EXPECT_TRUE(succeeded(job, r));
}

}  // namespace
}  // namespace locus::farm
