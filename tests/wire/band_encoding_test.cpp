// Band pixels on the wire (common/farm/band_codec.h; issue #25 item 4),
// over loopback: each job's bands travel in its output's encoding and the
// written frames hold a single-process render's pixels (a PNG job's frames
// joined from the workers' deflate streams, an EXR job's from their ZIP
// blocks; from a worker that does not
// offer png8+deflate, the bytes of the single-process render's); a worker of an
// older release that sends floats is still served; encoded pixels that do
// not decode are refused with INVALID_ARGUMENT naming the lease and the
// problem, and charged to the band like pixels of the wrong size.
#include <zstd.h>

#include <fstream>
#include <sstream>

#include "tests/farm_fixture.h"
#include "tests/wire/hand_worker.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class BandEncodingTest : public HandWorkerTest {
 protected:
  // The fetched frame file, byte for byte the single-process render's as
  // written by the same writer (expect_identical compares the pixels, and
  // writes the reference): a PNG job's whose bands came as rgb8+zstd, and
  // an EXR job's however its bands came (write_exr writes the blocks that
  // exr+zip bands carry). Not TIFF: its files carry the second they were
  // written.
  void expect_same_file(const JobInfo& job, const SubmitRequest& r, int frame) {
    ASSERT_NE(fs::path(r.output).extension(), ".tif");
    const std::string name = frame_path(fs::path(r.output).filename().string(), frame);
    const fs::path got = dir_ / ("got_" + job.job_id) / name;
    const fs::path ref =
        dir_ / ("ref_" + std::to_string(frame) + fs::path(r.output).extension().string());
    const std::string a = file_bytes(got);
    ASSERT_FALSE(a.empty()) << got;
    EXPECT_EQ(a, file_bytes(ref)) << name;
  }
};

TEST_F(BandEncodingTest, EachOutputsBandsTravelInItsEncodingAndFramesAreBitIdentical) {
  start();
  add_workers(2);
  struct Case {
    const char* output;
    BandEncoding encoding;
    int bands;
  };
  // 48 rows are 3 blocks of an EXR: in 3 bands each holds one (exr+zip), in
  // 5 none (float32+zstd, the frame stitched).
  for (const Case& c : {Case{"e_####.png", BandEncoding::kPng8Deflate, 5},
                        Case{"e_####.tif", BandEncoding::kRgb16Zstd, 5},
                        Case{"e_####.exr", BandEncoding::kExrZip, 3},
                        Case{"f_####.exr", BandEncoding::kFloat32Zstd, 5}}) {
    SCOPED_TRACE(c.output);
    // locus-worker offers png8+deflate and exr+zip (RegisterRequest.encodings).
    EXPECT_EQ(band_encoding_for(c.output, true, c.bands == 3), c.encoding);
    SubmitRequest r = request(kGlass, 64, 48, 1, 2, c.bands, c.output);
    const JobInfo job = run(r);
    expect_identical(job, r);  // the stored samples, read back exactly
    if (c.encoding == BandEncoding::kPng8Deflate) {
      // Joined from the bands' streams: an IDAT chunk a band, then the end.
      for (int f = 1; f <= 2; ++f) {
        const std::string a = file_bytes(dir_ / ("got_" + job.job_id) / frame_path("e_####.png", f));
        size_t chunks = 0;
        for (size_t at = a.find("IDAT"); at != std::string::npos; at = a.find("IDAT", at + 1))
          ++chunks;
        EXPECT_EQ(chunks, static_cast<size_t>(job.spec.bands) + 1) << "frame " << f;
      }
    }
    if (fs::path(c.output).extension() == ".exr") {
      // Joined from the bands' blocks (exr+zip) or stitched and written by
      // write_exr (float32+zstd): the single-process render's file either way.
      for (int f = 1; f <= 2; ++f) expect_same_file(job, r, f);
    }
  }
}

TEST_F(BandEncodingTest, TheLeaseNamesTheEncodingAndAnOlderWorkersFloatsAreAccepted) {
  const SubmitRequest r = request(kSpheres, 32, 16, 1, 1, 2, "o.png");
  const std::string job = start_with_job(r);
  ASSERT_FALSE(job.empty());
  HandWorker w = hand_worker();
  // Band 0 from a worker of this release, band 1 from an older one.
  for (bool older : {false, true}) {
    const auto task = w.lease();
    ASSERT_TRUE(task);
    EXPECT_EQ(task->encoding(), v1::BAND_RGB8_ZSTD);
    const v1::CompleteBandRequest req = w.render(*task, older);
    const int pixels = 32 * (task->y1() - task->y0());
    if (older) {
      EXPECT_EQ(req.rgb_size(), pixels * 3);
      EXPECT_TRUE(req.pixels().empty());
    } else {
      EXPECT_EQ(req.rgb_size(), 0);
      EXPECT_EQ(req.encoding(), v1::BAND_RGB8_ZSTD);
      EXPECT_EQ(req.width(), 32);
      EXPECT_EQ(req.rows(), task->y1() - task->y0());
      // At most the 3 bytes a pixel of the codes, and their compression.
      EXPECT_LE(req.pixels().size(), static_cast<size_t>(pixels) * 3);
    }
    v1::CompleteBandResponse resp;
    const grpc::Status st = w.send(req, &resp);
    ASSERT_TRUE(st.ok()) << st.error_message();
    EXPECT_TRUE(resp.accepted()) << resp.reason();
  }
  const std::optional<JobInfo> done = succeeded(job, r);
  ASSERT_TRUE(done);
  expect_same_file(*done, r, 1);
}

TEST_F(BandEncodingTest, PixelsThatDoNotDecodeAreRefusedAndChargedToTheBand) {
  start();
  HandWorker w = hand_worker();
  const SubmitRequest r = request(kSpheres, 16, 8, 1, 1, 1, "m.exr");
  auto job = client_->submit(r);
  ASSERT_TRUE(job.ok()) << job.status().message();

  const auto first = w.lease();
  ASSERT_TRUE(first);
  EXPECT_EQ(first->encoding(), v1::BAND_FLOAT32_ZSTD);
  v1::CompleteBandRequest bad = w.render(*first, false);
  ASSERT_GT(bad.pixels().size(), 10u);
  bad.mutable_pixels()->resize(bad.pixels().size() / 2);  // truncated on the way
  v1::CompleteBandResponse resp;
  grpc::Status st = w.send(bad, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("lease '" + first->lease_id() + "'"), std::string::npos)
      << st.error_message();
  EXPECT_NE(st.error_message().find("float32+zstd band of 16 x 8 pixels"), std::string::npos)
      << st.error_message();

  // Charged like pixels of the wrong size: the band is leased again, and the
  // job's history says why.
  const auto second = w.lease();
  ASSERT_TRUE(second);
  EXPECT_NE(second->lease_id(), first->lease_id());
  EXPECT_EQ(second->band(), first->band());
  auto events = client_->events(job->job_id, 0);
  ASSERT_TRUE(events.ok());
  bool named = false;
  for (const HistoryEntry& e : *events) {
    named |= e.text.find("sent malformed pixels") != std::string::npos &&
             e.text.find("corrupt or truncated") != std::string::npos;
  }
  EXPECT_TRUE(named);

  // An unknown encoding, and a zstd bomb (64 MiB of zeros in a few
  // kilobytes): refused the same way, without inflating it.
  v1::CompleteBandRequest unknown = w.render(*second, false);
  unknown.set_encoding(static_cast<v1::BandEncoding>(9));
  st = w.send(unknown, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("unknown encoding 9"), std::string::npos) << st.error_message();

  // (A worker that failed a job twice gets no more of it: another one.)
  HandWorker w2 = hand_worker();
  const auto third = w2.lease();
  ASSERT_TRUE(third);
  v1::CompleteBandRequest bomb = w2.render(*third, false);
  const std::string zeros(64u << 20, '\0');
  std::string z(ZSTD_compressBound(zeros.size()), '\0');
  z.resize(ZSTD_compress(z.data(), z.size(), zeros.data(), zeros.size(), 1));
  ASSERT_LT(z.size(), 64u << 10);
  bomb.set_pixels(z);
  st = w2.send(bomb, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("expected 1536"), std::string::npos) << st.error_message();

  // With max_attempts failures the job fails, naming the last problem.
  auto failed = client_->watch(job->job_id, [](const JobInfo&) {});
  ASSERT_TRUE(failed.ok());
  EXPECT_EQ(failed->state, JobState::kFailed);
  EXPECT_NE(failed->error.find("malformed pixels"), std::string::npos) << failed->error;
}

}  // namespace
}  // namespace locus::farm
