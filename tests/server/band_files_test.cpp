// A band's record as the coordinator's store keeps it and a frame's files
// made from its bands' records (server/band_files.h): records packed and
// checked (torn, foreign, damaged), the cost counts riding with the pixels,
// frames stitched or joined from png8+deflate bands, cost maps joined, and
// band edges as text.
#include "server/band_files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <map>

#include "common/base/cost_map.h"
#include "common/base/exr.h"
#include "common/base/image.h"
#include "tests/server/scheduler_doubles.h"

namespace locus::farm {
namespace {

namespace fs = std::filesystem;
using test_doubles::TempDir;

std::string file_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(BandFiles, EdgesAsTextRoundTripAndAreChecked) {
  EXPECT_EQ(band_edges_text({0, 2, 7}), "0 2 7");
  EXPECT_EQ(*band_edges_from_text("0 2 7", 7, 2), (std::vector<int>{0, 2, 7}));
  EXPECT_TRUE(band_edges_from_text("", 7, 2)->empty());
  for (const char* bad : {"0 2", "0 3 2 7", "0 2 8", "1 2 7", "0 x 7", "0 2 2 7"}) {
    EXPECT_FALSE(band_edges_from_text(bad, 7, 2).ok()) << bad;
  }
}

// A band's pixels as the store keeps them, in the encoding they travelled in.
EncodedBand float_band(const BandPixels& rows, const std::vector<float>& rgb) {
  BandOutput out;
  out.rgb = rgb;
  return stored_band(out, rows);
}

TEST(BandFiles, PackUnpackAndRejectTornOrForeignRecords) {
  const BandPixels rows{3, 2, 4};
  std::vector<float> rgb(3 * 2 * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = 0.25f * static_cast<float>(i);
  const std::string record = pack_band(rows, float_band(rows, rgb));
  auto back = unpack_band(record, rows);
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(*back, rgb);
  EXPECT_FALSE(unpack_band(record, {3, 2, 5}).ok());  // other rows
  // A torn record and a flipped bit are refused, never pixels.
  EXPECT_FALSE(unpack_band(record.substr(0, record.size() - 5), rows).ok());
  std::string flipped = record;
  flipped[40] ^= 0x7f;
  EXPECT_FALSE(unpack_band(flipped, rows).ok());
  EXPECT_FALSE(unpack_band("", rows).ok());
  // An encoded band (an 8-bit PNG job's) keeps its bytes and decodes.
  auto png = encode_band(BandEncoding::kRgb8Zstd, 3, 2, rgb);
  ASSERT_TRUE(png.ok());
  BandOutput out;
  out.encoded = *png;
  const std::string small = pack_band(rows, stored_band(out, rows));
  EXPECT_LT(small.size(), record.size());
  auto decoded = unpack_band(small, rows);
  ASSERT_TRUE(decoded.ok()) << decoded.status().message();
  auto direct = decode_band(*png);
  ASSERT_TRUE(direct.ok());
  EXPECT_EQ(*decoded, *direct);
}

// A job with cost maps: the band's counts ride in its record (LOCBAND3),
// checked by the same checksum; a record without them (LOCBAND2, a job
// without cost maps, or an older worker) has none; stitch_cost joins a
// frame's bands' counts, leaving a band without counts zero.
TEST(BandFiles, CostCountsRideInTheRecordAndAreJoinedIntoTheFrames) {
  const FrameReady f{"j0001", 2, "f_0002.exr", 4, 5, 2, {0, 2, 5}, "c_0002.png"};
  CostBuffer want;
  want.reset(4, 0, 5);
  for (size_t i = 0; i < want.pixels.size(); ++i) {
    want.pixels[i].rays_eye = static_cast<uint32_t>(i + 1);
    want.pixels[i].tests_shadow_volume = static_cast<uint32_t>(3 * i);
    want.pixels[i].traced = i % 3 == 0;
    want.pixels[i].traced_span = i % 6 == 0;
  }
  std::map<int, std::string> records;
  for (int b = 0; b < 2; ++b) {
    const Band rows = band_rows(5, 2, f.band_edges, b);
    const BandPixels px{4, rows.y0, rows.y1};
    CostBuffer part;
    part.reset(4, rows.y0, rows.y1);
    std::copy(want.pixels.begin() + rows.y0 * 4, want.pixels.begin() + rows.y1 * 4,
              part.pixels.begin());
    const std::vector<float> rgb(static_cast<size_t>(4) * (rows.y1 - rows.y0) * 3, 0.5f);
    records[b] = pack_band(px, float_band(px, rgb), *encode_band_cost(part));
    // The pixels read as from any record; the counts come back as sent.
    auto pixels = unpack_band(records[b], px);
    ASSERT_TRUE(pixels.ok()) << pixels.status().message();
    EXPECT_EQ(*pixels, rgb);
    auto counts = unpack_cost(records[b], px);
    ASSERT_TRUE(counts.ok());
    EXPECT_EQ(*counts, *encode_band_cost(part));
    // A flipped bit in the counts fails the checksum: neither is trusted.
    std::string flipped = records[b];
    flipped[flipped.size() - 12] ^= 0x10;
    EXPECT_FALSE(unpack_band(flipped, px).ok());
    EXPECT_FALSE(unpack_cost(flipped, px).ok());
    // A record without counts has none.
    auto plain = unpack_cost(pack_band(px, float_band(px, rgb)), px);
    ASSERT_TRUE(plain.ok());
    EXPECT_TRUE(plain->empty());
  }
  const auto lookup = [&](int band) -> Result<std::string_view> {
    auto it = records.find(band);
    if (it == records.end()) return NotFound("band " + std::to_string(band));
    return std::string_view(it->second);
  };
  auto joined = stitch_cost(f, lookup);
  ASSERT_TRUE(joined.ok()) << joined.status().message();
  ASSERT_EQ(joined->pixels.size(), want.pixels.size());
  for (size_t i = 0; i < want.pixels.size(); ++i) {
    EXPECT_EQ(joined->pixels[i].rays_eye, want.pixels[i].rays_eye) << i;
    EXPECT_EQ(joined->pixels[i].tests_shadow_volume, want.pixels[i].tests_shadow_volume) << i;
    EXPECT_EQ(joined->pixels[i].traced_span, want.pixels[i].traced_span) << i;
  }
  // A band without counts (a worker of an older release): its rows zero.
  {
    const BandPixels px{4, 2, 5};
    records[1] = pack_band(px, float_band(px, std::vector<float>(36, 0.5f)));
  }
  joined = stitch_cost(f, lookup);
  ASSERT_TRUE(joined.ok()) << joined.status().message();
  EXPECT_EQ(joined->pixels[7].rays_eye, 8u);
  EXPECT_EQ(joined->pixels[8].rays_eye, 0u);
  EXPECT_EQ(joined->totals().rays_eye, 1u + 2 + 3 + 4 + 5 + 6 + 7 + 8);
  // A missing band is an error naming it.
  records.erase(0);
  EXPECT_EQ(stitch_cost(f, lookup).status().code(), Code::kNotFound);
}

TEST(BandFiles, StitchAFrameFromItsBandRecords) {
  TempDir dir;
  const FrameReady f{"j0001", 4, "f_0004.exr", 5, 7, 3, {}, ""};
  Image expected(5, 7);
  for (size_t i = 0; i < expected.rgb.size(); ++i) expected.rgb[i] = static_cast<float>(i);
  std::map<int, std::string> records;
  for (int b = 0; b < 3; ++b) {
    const Band rows = band_rows(7, 3, b);
    std::vector<float> rgb(expected.rgb.begin() + rows.y0 * 15,
                           expected.rgb.begin() + rows.y1 * 15);
    const BandPixels px{5, rows.y0, rows.y1};
    records[b] = pack_band(px, float_band(px, rgb));
  }
  const auto lookup = [&](int band) -> Result<std::string> {
    auto it = records.find(band);
    if (it == records.end()) return NotFound("band " + std::to_string(band));
    return it->second;
  };
  auto image = stitch_frame(f, lookup);
  ASSERT_TRUE(image.ok()) << image.status().message();
  EXPECT_EQ(image->rgb, expected.rgb);
  ASSERT_TRUE(write_frame_file(dir.path.string(), f.file_name, *image, true).ok());
  auto read = read_image((dir.path / f.file_name).string());
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->rgb, expected.rgb);
  EXPECT_FALSE(fs::exists(dir.path / (".partial-" + f.file_name)));
  records.erase(1);
  EXPECT_EQ(stitch_frame(f, lookup).status().code(), Code::kNotFound);
  records[1] = records[0];  // another band's record: the rows do not match
  EXPECT_FALSE(stitch_frame(f, lookup).ok());
}

// write_frame: a PNG frame whose bands all came as png8+deflate is joined
// from their bytes (one IDAT chunk a band, and the stream's end); a frame
// with a band of another encoding (an older worker's) is stitched and
// written by OpenImageIO. The pixels are the same either way.
TEST(BandFiles, APngFrameIsJoinedFromDeflatedBandsOrElseStitched) {
  TempDir dir;
  const int width = 6, height = 9;
  const std::vector<int> edges{0, 2, 7, 9};
  const FrameReady f{"j0001", 3, "f_0003.png", width, height, 3, edges, ""};
  Image expected(width, height);
  for (size_t i = 0; i < expected.rgb.size(); ++i)
    expected.rgb[i] = static_cast<float>((i * 37) % 256) / 255.0f;
  const auto records = [&](bool older_middle) {
    std::map<int, std::string> r;
    for (int b = 0; b < 3; ++b) {
      const BandPixels px{width, edges[b], edges[b + 1]};
      const std::vector<float> rgb(expected.rgb.begin() + edges[b] * width * 3,
                                   expected.rgb.begin() + edges[b + 1] * width * 3);
      const BandEncoding e =
          older_middle && b == 1 ? BandEncoding::kRgb8Zstd : BandEncoding::kPng8Deflate;
      auto enc = encode_band(e, width, edges[b + 1] - edges[b], rgb);
      EXPECT_TRUE(enc.ok());
      r[b] = pack_band(px, *enc);
    }
    return r;
  };
  const auto count = [](const std::string& s, const std::string& word) {
    size_t n = 0;
    for (size_t at = s.find(word); at != std::string::npos; at = s.find(word, at + 1)) ++n;
    return n;
  };
  // The pixels as write_image writes them (8-bit codes, read back).
  ASSERT_TRUE(write_image((dir.path / "reference.png").string(), expected).ok());
  auto reference = read_image((dir.path / "reference.png").string());
  ASSERT_TRUE(reference.ok());
  for (bool older_middle : {false, true}) {
    SCOPED_TRACE(older_middle ? "one band rgb8+zstd" : "all png8+deflate");
    const std::map<int, std::string> r = records(older_middle);
    std::map<int, int> reads;  // each band's record is read once, either way
    const auto lookup = [&](int band) -> Result<std::string> {
      ++reads[band];
      return r.at(band);
    };
    const fs::path out = dir.path / (older_middle ? "stitched" : "joined");
    FrameWrite how = FrameWrite::kJoined;
    ASSERT_TRUE(write_frame(out.string(), f, lookup, true, true, &how).ok());
    EXPECT_EQ(how, older_middle ? FrameWrite::kEncoded : FrameWrite::kJoined);
    EXPECT_EQ(reads, (std::map<int, int>{{0, 1}, {1, 1}, {2, 1}}));
    auto read = read_image((out / f.file_name).string());
    ASSERT_TRUE(read.ok()) << read.status().message();
    EXPECT_EQ(read->rgb, reference->rgb);
    EXPECT_FALSE(fs::exists(out / (".partial-" + f.file_name)));
    const std::string bytes = file_of(out / f.file_name);
    if (older_middle) {
      EXPECT_EQ(count(bytes, "IDAT"), 1u);  // one stream, OpenImageIO's
    } else {
      EXPECT_EQ(count(bytes, "IDAT"), 4u);  // a chunk a band, then the stream's end
    }
  }
  // A damaged record is an error naming it, and nothing is written.
  std::map<int, std::string> r = records(false);
  r[2][r[2].size() / 2] ^= 0x55;
  const auto lookup = [&](int band) -> Result<std::string> { return r.at(band); };
  const fs::path out = dir.path / "damaged";
  EXPECT_FALSE(write_frame(out.string(), f, lookup, true).ok());
  EXPECT_FALSE(fs::exists(out / f.file_name));
}

// write_frame: an EXR frame whose bands all came as exr+zip is written from
// their blocks; a frame with a band of another encoding, or one whose
// blocks are not where its rows are, is stitched and written by write_exr.
// The file is write_exr's, byte for byte, every way. Rows 0-1, 2-20,
// 21-39: blocks 0 and 1 across bands.
TEST(BandFiles, AnExrFrameIsWrittenFromZippedBandsOrElseStitched) {
  TempDir dir;
  const int width = 6, height = 40;
  const std::vector<int> edges{0, 2, 21, 40};
  const FrameReady f{"j0001", 3, "f_0003.exr", width, height, 3, edges, ""};
  Image expected(width, height);
  for (size_t i = 0; i < expected.rgb.size(); ++i)
    expected.rgb[i] = static_cast<float>(i % 97) / 64.0f - 0.25f;
  ASSERT_TRUE(write_exr((dir.path / "reference.exr").string(), expected).ok());
  const std::string reference = file_of(dir.path / "reference.exr");
  enum class Case { kZipped, kOlderMiddle, kMisplacedMiddle };
  const auto records = [&](Case c) {
    std::map<int, std::string> r;
    for (int b = 0; b < 3; ++b) {
      const BandPixels px{width, edges[b], edges[b + 1]};
      const std::vector<float> rgb(expected.rgb.begin() + edges[b] * width * 3,
                                   expected.rgb.begin() + edges[b + 1] * width * 3);
      const bool middle = b == 1;
      const BandEncoding e =
          middle && c == Case::kOlderMiddle ? BandEncoding::kFloat32Zstd : BandEncoding::kExrZip;
      // Misplaced: encoded as if it began the frame.
      const int y0 = middle && c == Case::kMisplacedMiddle ? 0 : edges[b];
      auto enc = encode_band(e, width, edges[b + 1] - edges[b], rgb, y0, height);
      EXPECT_TRUE(enc.ok());
      r[b] = pack_band(px, *enc);
    }
    return r;
  };
  for (Case c : {Case::kZipped, Case::kOlderMiddle, Case::kMisplacedMiddle}) {
    SCOPED_TRACE(static_cast<int>(c));
    const std::map<int, std::string> r = records(c);
    std::map<int, int> reads;  // each band's record is read once, either way
    const auto lookup = [&](int band) -> Result<std::string> {
      ++reads[band];
      return r.at(band);
    };
    const fs::path out = dir.path / std::to_string(static_cast<int>(c));
    FrameWrite how = FrameWrite::kJoined;
    ASSERT_TRUE(write_frame(out.string(), f, lookup, true, true, &how).ok());
    EXPECT_EQ(reads, (std::map<int, int>{{0, 1}, {1, 1}, {2, 1}}));
    auto read = read_image((out / f.file_name).string());
    ASSERT_TRUE(read.ok()) << read.status().message();
    EXPECT_EQ(read->rgb, expected.rgb);
    EXPECT_FALSE(fs::exists(out / (".partial-" + f.file_name)));
    EXPECT_EQ(how, c == Case::kZipped ? FrameWrite::kJoined : FrameWrite::kEncoded);
    EXPECT_TRUE(file_of(out / f.file_name) == reference);
  }
  // A damaged record is an error naming it, and nothing is written.
  std::map<int, std::string> r = records(Case::kZipped);
  r[2][r[2].size() / 2] ^= 0x55;
  const auto lookup = [&](int band) -> Result<std::string> { return r.at(band); };
  const fs::path out = dir.path / "damaged";
  const Status s = write_frame(out.string(), f, lookup, true);
  EXPECT_FALSE(s.ok());
  EXPECT_FALSE(fs::exists(out / f.file_name));
}

}  // namespace
}  // namespace locus::farm
