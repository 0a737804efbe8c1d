// Results a worker should not send (issue #25 item 6): pixels of the wrong
// size, a lease it does not hold (another worker's, or one never granted),
// pixels of another job's band under a lease. Each is refused with a
// reason naming the lease and the problem; nothing of it is stored (no file
// under the job's directory, no band in the store); the lease of the
// band's real holder stands; the farm goes on. No network: Coordinators and
// workers played by the test.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "common/farm/band_codec.h"
#include "server/coordinator.h"
#include "server/store.h"
#include "tests/farm_fixture.h"
#include "tests/server/coordinator_doubles.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {
namespace fs = std::filesystem;
using test_doubles::TempDir;
using test_doubles::TestWorker;
using testing_farm::kSpheres;
using testing_farm::request;

class BadResults : public ::testing::Test {
 protected:
  void SetUp() override {
    c_ = std::make_unique<Coordinator>(test_doubles::test_options(dir_.path));
    ASSERT_TRUE(c_->start().ok());
    a_job_ = c_->submit(request(kSpheres, 16, 12, 1, 1, 2, "a_####.exr"))->job_id;
    b_job_ = c_->submit(request(kSpheres, 20, 12, 1, 1, 2, "b_####.png"))->job_id;
    a_ = std::make_unique<TestWorker>(*c_, "a:1");
    b_ = std::make_unique<TestWorker>(*c_, "b:2");
  }
  void TearDown() override {
    c_->shutdown();
    // In the store, each band accepted once from its good result; the
    // refused results count for nothing.
    auto store = JobStore::open((dir_.path / "data" / "locus.db").string());
    ASSERT_TRUE(store.ok()) << store.status().message();
    for (const std::string& job : {a_job_, b_job_}) {
      for (int band : {0, 1}) {
        EXPECT_EQ(*(*store)->band_completions(job, 1, band), static_cast<int>(accepted_.count({job, band})))
            << job << " band " << band;
      }
    }
  }

  // Files under the job's directory: band files, temporaries, frames.
  int files(const std::string& job) {
    int n = 0;
    std::error_code ec;
    for (const auto& e : fs::recursive_directory_iterator(c_->job_dir(job), ec)) {
      n += e.is_regular_file() ? 1 : 0;
    }
    return n;
  }
  // Nothing of the band is kept: not done, nothing on disk, the job's
  // count unchanged.
  void expect_nothing_stored(const BandLease& t) {
    auto frame = c_->frame_detail(t.job_id, t.frame);
    ASSERT_TRUE(frame.ok());
    EXPECT_NE(frame->bands.at(t.band).state, "done");
    EXPECT_EQ(files(t.job_id), 0);
    EXPECT_EQ(c_->job(t.job_id)->bands_done, 0);
  }
  // A good result, accepted.
  void accept(TestWorker& w, const BandLease& t) {
    EXPECT_TRUE(w.complete(t));
    accepted_.insert({t.job_id, t.band});
  }
  BandLease take(TestWorker& w, const std::string& job) {
    auto t = w.take();
    EXPECT_TRUE(t.has_value());
    EXPECT_EQ(t->job_id, job);
    return *t;
  }

  TempDir dir_;
  std::unique_ptr<Coordinator> c_;
  std::string a_job_, b_job_;
  std::unique_ptr<TestWorker> a_, b_;
  std::set<std::pair<std::string, int>> accepted_;  // job, band (frame 1)
};

TEST_F(BadResults, PixelsOfTheWrongSizeAreRefusedAndTheBandLeasedAgain) {
  // One float short from a, three too many from b (the band requeued to the
  // front, so b gets it next): two failures, under the attempt limit.
  const BandLease t = take(*a_, a_job_);
  const size_t right = static_cast<size_t>(t.width) * (t.y1 - t.y0) * 3;
  for (TestWorker* w : {a_.get(), b_.get()}) {
    const size_t size = w == a_.get() ? right - 1 : right + 3;
    SCOPED_TRACE(size);
    const BandLease lease = w == a_.get() ? t : take(*w, a_job_);
    EXPECT_EQ(lease.band, t.band);
    BandOutput out = w->render(lease);
    out.encoded = {};  // plain floats, as a worker of 0.13 sends them
    out.rgb.assign(size, 0.5f);
    auto r = c_->complete_band(out);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
    const std::string& why = r.status().message();
    EXPECT_NE(why.find("lease '" + lease.lease_id + "'"), std::string::npos) << why;
    EXPECT_NE(why.find("expected " + std::to_string(right) + " floats"), std::string::npos) << why;
    EXPECT_NE(why.find("got " + std::to_string(size)), std::string::npos) << why;
    expect_nothing_stored(lease);
    // The malformed lease is over: the same result again is stale.
    EXPECT_FALSE(w->complete(lease));
  }
  const BandLease again = take(*a_, a_job_);
  EXPECT_EQ(again.band, t.band);
  accept(*a_, again);
  EXPECT_EQ(c_->job(a_job_)->state, JobState::kRunning);
}

// Encoded pixels that decode, and hold as many values as the band, but
// for another shape (half as wide, twice as tall): refused by their size,
// not counted as the band's (they would scramble its rows).
TEST_F(BadResults, EncodedPixelsOfAnotherShapeAreRefused) {
  const BandLease t = take(*a_, a_job_);
  const int rows = t.y1 - t.y0;
  ASSERT_EQ(t.width % 2, 0);
  BandOutput out = a_->render(t);
  ASSERT_FALSE(out.encoded.bytes.empty());
  auto reshaped = encode_band(out.encoded.encoding, t.width / 2, rows * 2,
                              std::vector<float>(static_cast<size_t>(t.width) * rows * 3, 0.25f));
  ASSERT_TRUE(reshaped.ok()) << reshaped.status().message();
  out.encoded = std::move(*reshaped);
  auto r = c_->complete_band(out);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  const std::string want = "expected " + std::to_string(t.width) + " x " + std::to_string(rows) +
                           " pixels, got " + std::to_string(t.width / 2) + " x " +
                           std::to_string(rows * 2);
  EXPECT_NE(r.status().message().find(want), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("lease '" + t.lease_id + "'"), std::string::npos);
  expect_nothing_stored(t);
  const BandLease again = take(*b_, a_job_);
  EXPECT_EQ(again.band, t.band);
  accept(*b_, again);
}

// Cost counts (a job with cost maps, docs/cost-map.md) that do not decode,
// or are of another band's size: the whole result is refused as malformed,
// naming the lease and the counts, and nothing of it is kept.
TEST_F(BadResults, MalformedCostCountsAreRefusedWithTheirPixels) {
  const BandLease t = take(*a_, a_job_);
  const int pixels = t.width * (t.y1 - t.y0);
  CostBuffer other;
  other.reset(t.width, 0, t.y1 - t.y0 + 1);
  for (const std::string& cost : {std::string("not zstd"), *encode_band_cost(other)}) {
    const BandLease lease = cost == "not zstd" ? t : take(*b_, a_job_);
    EXPECT_EQ(lease.band, t.band);
    BandOutput out = (cost == "not zstd" ? a_ : b_)->render(lease);
    out.cost = cost;
    auto r = c_->complete_band(out);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
    const std::string& why = r.status().message();
    EXPECT_NE(why.find("lease '" + lease.lease_id + "'"), std::string::npos) << why;
    EXPECT_NE(why.find("cost counts of a band of " + std::to_string(pixels) + " pixels"),
              std::string::npos)
        << why;
    expect_nothing_stored(lease);
  }
  const BandLease again = take(*a_, a_job_);
  EXPECT_EQ(again.band, t.band);
  accept(*a_, again);
}

TEST_F(BadResults, AnotherWorkersLeaseIsRefusedAndStaysItsHolders) {
  const BandLease t = take(*a_, a_job_);
  auto r = c_->complete_band(b_->render(t));  // b returns a's band
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_FALSE(r->accepted);
  EXPECT_NE(r->reason.find("lease '" + t.lease_id + "' is not held by this worker"),
            std::string::npos)
      << r->reason;
  expect_nothing_stored(t);
  // b's heartbeat for it is told to drop it; a's renews it, untouched.
  EXPECT_EQ(*c_->heartbeat(b_->id, {t.lease_id}), std::vector<std::string>{t.lease_id});
  EXPECT_TRUE(c_->heartbeat(a_->id, {t.lease_id})->empty());
  accept(*a_, t);
  auto frame = c_->frame_detail(a_job_, t.frame);
  EXPECT_EQ(frame->bands.at(t.band).state, "done");
  EXPECT_EQ(frame->bands.at(t.band).worker_name, "a:1");
}

TEST_F(BadResults, ALeaseNeverGrantedIsRefused) {
  const BandLease t = take(*a_, a_job_);
  BandOutput out = b_->render(t);
  out.lease_id = "0badf00d-7";
  auto r = c_->complete_band(out);
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_FALSE(r->accepted);
  EXPECT_NE(r->reason.find("lease '0badf00d-7' is not held by this worker"), std::string::npos)
      << r->reason;
  expect_nothing_stored(t);
  EXPECT_EQ(files(b_job_), 0);
  accept(*a_, t);
}

// A worker holding bands of two jobs returns one job's pixels under the
// other's lease: the lease alone says where a result goes, so the pixels
// are measured against its band, refused, and the other lease is unharmed.
TEST_F(BadResults, PixelsOfAnotherJobsBandAreRefused) {
  const BandLease mine = take(*a_, a_job_);
  const BandLease other = take(*a_, b_job_);
  ASSERT_NE(mine.width, other.width);
  BandOutput out = a_->render(other);
  out.lease_id = mine.lease_id;
  auto r = c_->complete_band(out);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  EXPECT_NE(r.status().message().find("lease '" + mine.lease_id + "'"), std::string::npos)
      << r.status().message();
  EXPECT_NE(r.status().message().find("job " + a_job_), std::string::npos) << r.status().message();
  expect_nothing_stored(mine);
  expect_nothing_stored(other);
  accept(*a_, other);
  // The refused band goes back to the queue, to a worker that has not
  // failed it first.
  const BandLease again = take(*b_, a_job_);
  EXPECT_EQ(again.band, mine.band);
  accept(*b_, again);
  // The history names the refused result.
  bool named = false;
  auto history = c_->events(a_job_, 0, 100);
  ASSERT_TRUE(history.ok());
  for (const HistoryEntry& e : *history) {
    named |= e.text.find("lease " + mine.lease_id) != std::string::npos &&
             e.text.find("malformed") != std::string::npos;
  }
  EXPECT_TRUE(named);
}

}  // namespace
}  // namespace locus::farm
