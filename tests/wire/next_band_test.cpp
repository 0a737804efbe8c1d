// The next band with a result's answer (CompleteBandRequest.want_next,
// issue #25 "fewer calls per band"), over loopback: a worker that asks gets
// its next lease in CompleteBandResponse.next, as a GetTask with wait_ms 0
// would have given it, and no band is lost or leased twice; a hand-back or a
// worker that does not ask (an older release) gets none; the farm's own
// workers use it and still render frames identical to a single process.
#include "tests/farm_fixture.h"
#include "tests/wire/hand_worker.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

using NextBandTest = HandWorkerTest;

TEST_F(NextBandTest, EachAnswerCarriesTheNextBandUntilNoneIsLeft) {
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 3, "n.png");
  const std::string job = start_with_job(r);
  ASSERT_FALSE(job.empty());
  HandWorker w = hand_worker();
  std::optional<v1::BandTask> task = w.lease();  // the first by GetTask
  ASSERT_TRUE(task);
  std::set<int> bands;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(task) << "answer " << i;
    EXPECT_TRUE(bands.insert(task->band()).second) << "band " << task->band() << " twice";
    v1::CompleteBandRequest req = w.render(*task, false);
    req.set_want_next(true);
    v1::CompleteBandResponse resp;
    const grpc::Status st = w.send(req, &resp);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_TRUE(resp.accepted()) << resp.reason();
    // Always answered (a band, or none: the job's bands are all out).
    ASSERT_TRUE(resp.has_next());
    EXPECT_FALSE(resp.next().drain());
    task.reset();
    if (resp.next().has_task()) task = resp.next().task();
    EXPECT_EQ(resp.next().has_task(), i < 2) << "answer " << i;
  }
  EXPECT_EQ(bands, (std::set<int>{0, 1, 2}));
  EXPECT_TRUE(succeeded(job, r));
}

TEST_F(NextBandTest, AHandBackOrAWorkerThatDoesNotAskGetsNone) {
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 3, "h.png");
  const std::string job = start_with_job(r);
  ASSERT_FALSE(job.empty());
  HandWorker w = hand_worker();

  // A hand-back is the worker leaving: no next band, whatever it asks.
  std::optional<v1::BandTask> task = w.lease();
  ASSERT_TRUE(task);
  v1::CompleteBandRequest back;
  back.set_worker_id(w.id());
  back.set_lease_id(task->lease_id());
  back.set_handed_back(true);
  back.set_want_next(true);
  v1::CompleteBandResponse resp;
  ASSERT_TRUE(w.send(back, &resp).ok());
  EXPECT_FALSE(resp.has_next());

  // A result without want_next (an older worker): none either, and the
  // band handed back is leased again by GetTask.
  std::set<int> bands;
  while (std::optional<v1::BandTask> t = w.lease()) {
    bands.insert(t->band());
    v1::CompleteBandResponse answer;
    ASSERT_TRUE(w.send(w.render(*t, false), &answer).ok());
    EXPECT_TRUE(answer.accepted()) << answer.reason();
    EXPECT_FALSE(answer.has_next());
    if (bands.size() == 3) break;
  }
  EXPECT_EQ(bands, (std::set<int>{0, 1, 2}));
  EXPECT_TRUE(succeeded(job, r));
}

TEST_F(NextBandTest, AStaleResultIsRefusedAndStillAnsweredWithABand) {
  // A result for a lease the coordinator no longer knows is dropped, and
  // the worker asking is free for work all the same.
  const SubmitRequest r = request(kSpheres, 32, 24, 1, 1, 2, "s.png");
  ASSERT_FALSE(start_with_job(r).empty());
  HandWorker w = hand_worker();
  std::optional<v1::BandTask> task = w.lease();
  ASSERT_TRUE(task);
  v1::CompleteBandRequest req = w.render(*task, false);
  req.set_lease_id("l-not-a-lease");
  req.set_want_next(true);
  v1::CompleteBandResponse resp;
  ASSERT_TRUE(w.send(req, &resp).ok());
  EXPECT_FALSE(resp.accepted());
  ASSERT_TRUE(resp.has_next());
  ASSERT_TRUE(resp.next().has_task());
  EXPECT_NE(resp.next().task().band(), task->band());
}

}  // namespace
}  // namespace locus::farm
