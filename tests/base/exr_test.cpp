// EXR files joined from blocks compressed elsewhere (common/base/exr.h):
// a block's ZIP form round-trips bit for bit, a file written from blocks is
// read by OpenEXR as the same pixels write_exr writes, in as many bytes
// give or take the header, and data that is not a block's is refused.
#include "common/base/exr.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

namespace locus {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  const fs::path d =
      fs::temp_directory_path() /
      ("locus-exr-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// A smooth image, as renders are, with a few values no PNG keeps.
Image smooth_image(int w, int h) {
  Image img(w, h);
  for (size_t i = 0; i < img.rgb.size(); ++i)
    img.rgb[i] = static_cast<float>(std::sin(0.001 * static_cast<double>(i)) * 0.7 + 0.45);
  img.rgb[0] = -0.5f;
  img.rgb[1] = 1.5e6f;
  img.rgb[5] = std::numeric_limits<float>::infinity();
  return img;
}

// Any 32-bit patterns: NaN payloads, signed zeros, subnormals; they do not
// compress.
std::vector<float> any_bits(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<float> v(n);
  for (float& f : v) {
    const uint32_t bits = rng();
    std::memcpy(&f, &bits, 4);
  }
  return v;
}

TEST(ExrBlocks, ABlockRoundTripsBitForBit) {
  for (int width : {1, 7, 300}) {
    for (int rows : {1, 5, kExrZipBlockRows}) {
      SCOPED_TRACE(std::to_string(width) + " x " + std::to_string(rows));
      const size_t n = static_cast<size_t>(width) * rows * 3;
      const Image smooth = smooth_image(width, rows);
      for (const std::vector<float>& rgb : {smooth.rgb, any_bits(n, 27)}) {
        const std::string block = exr_zip_block(rgb.data(), width, rows);
        ASSERT_LE(block.size(), n * 4);
        std::vector<float> back(n, 0.0f);
        const Status s = exr_unzip_block(block, width, rows, back.data(), "block");
        ASSERT_TRUE(s.ok()) << s.message();
        EXPECT_EQ(std::memcmp(back.data(), rgb.data(), n * 4), 0);
      }
      // Random bits do not shrink: the block is kept as laid out, which is
      // how an EXR reader tells it from a compressed one.
      EXPECT_EQ(exr_zip_block(any_bits(n, 5).data(), width, rows).size(), n * 4);
    }
  }
  // A smooth block shrinks, a flat one to almost nothing.
  const Image wide = smooth_image(300, kExrZipBlockRows);
  const size_t raw = static_cast<size_t>(300) * kExrZipBlockRows * 12;
  EXPECT_LT(exr_zip_block(wide.rgb.data(), 300, kExrZipBlockRows).size(), raw);
  const std::vector<float> flat(raw / 4, 0.25f);
  EXPECT_LT(exr_zip_block(flat.data(), 300, kExrZipBlockRows).size(), raw / 100);
}

// A frame of 300 x 70 (its last block of 6 rows) from its blocks: OpenEXR
// reads the very floats, and the file is write_exr's, byte for byte
// (write_exr compresses the same blocks the same way).
TEST(ExrBlocks, AFileWrittenFromBlocksReadsAsWriteExrsFile) {
  const int width = 300, height = 70;
  const Image img = smooth_image(width, height);
  std::vector<std::string> blocks;
  for (int y = 0; y < height; y += kExrZipBlockRows) {
    const int rows = std::min(kExrZipBlockRows, height - y);
    blocks.push_back(exr_zip_block(img.pixel(0, y), width, rows));
  }
  const fs::path dir = temp_dir();
  const std::vector<std::string_view> views(blocks.begin(), blocks.end());
  const Status written = write_exr_blocks((dir / "blocks.exr").string(), width, height, views);
  ASSERT_TRUE(written.ok()) << written.message();
  ASSERT_TRUE(write_exr((dir / "whole.exr").string(), img).ok());
  auto a = read_exr((dir / "blocks.exr").string());
  ASSERT_TRUE(a.ok()) << a.status().message();
  EXPECT_EQ(a->width, width);
  EXPECT_EQ(a->height, height);
  EXPECT_EQ(std::memcmp(a->rgb.data(), img.rgb.data(), img.rgb.size() * 4), 0);
  const auto bytes = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string joined = bytes(dir / "blocks.exr");
  EXPECT_TRUE(joined == bytes(dir / "whole.exr"))
      << joined.size() << " bytes against " << fs::file_size(dir / "whole.exr");
  EXPECT_LT(joined.size(), static_cast<size_t>(width) * height * 12);
  // One block short: refused, naming the file; nothing is left behind.
  const std::vector<std::string_view> fewer(views.begin(), views.end() - 1);
  const Status s = write_exr_blocks((dir / "short.exr").string(), width, height, fewer);
  EXPECT_EQ(s.code(), Code::kInvalidArgument);
  EXPECT_NE(s.message().find("short.exr: 4 blocks for 70 rows, expected 5"), std::string::npos)
      << s.message();
}

TEST(ExrBlocks, DataThatIsNotTheBlocksIsRefused) {
  const int width = 8, rows = 4;
  std::vector<float> out(static_cast<size_t>(width) * rows * 3);
  const auto refused = [&](std::string_view data, const std::string& words) {
    const Status s = exr_unzip_block(data, width, rows, out.data(), "band 3, block 1");
    EXPECT_EQ(s.code(), Code::kInvalidArgument) << words;
    EXPECT_NE(s.message().find("band 3, block 1: not a ZIP block of 4 rows of 8 pixels"),
              std::string::npos)
        << s.message();
    EXPECT_NE(s.message().find(words), std::string::npos) << s.message();
  };
  refused("not a zlib stream", "corrupt zlib stream");
  const auto zipped = [](size_t bytes) {
    const std::string raw(bytes, '\1');
    uLongf size = compressBound(static_cast<uLong>(bytes));
    std::string z(size, '\0');
    compress2(reinterpret_cast<Bytef*>(z.data()), &size, reinterpret_cast<const Bytef*>(raw.data()),
              static_cast<uLong>(bytes), 6);
    z.resize(size);
    return z;
  };
  // 384 bytes make the block; a stream of more, or fewer, is not it.
  refused(zipped(1 << 20), "more bytes than the rows hold");
  refused(zipped(100), "100 bytes, expected 384");
  refused(zipped(384) + "x", "1 bytes after the zlib stream");
  std::string cut = zipped(384);
  cut.resize(cut.size() - 3);
  refused(cut, "corrupt zlib stream");
  EXPECT_TRUE(exr_unzip_block(zipped(384), width, rows, out.data(), "block").ok());
}

}  // namespace
}  // namespace locus
