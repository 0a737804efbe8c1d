// Image files (common/base/image.h, png.h, image_plugin.h): PNGs written by
// Locus's own writer, EXR and TIFF through the image plugin, all read back
// by the plugin (OpenImageIO), which checks every chunk's CRC and the
// zlib stream's adler-32 as it decodes.
#include "common/base/image.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "common/base/png.h"

namespace locus {
namespace {

namespace fs = std::filesystem;

// (A code c reads back as c / 255 to within a float's rounding: compared
// as codes.)

// Values across the range and beyond it: negatives, over 1, NaN, +inf.
Image test_image(int w, int h) {
  Image img(w, h);
  for (size_t i = 0; i < img.rgb.size(); ++i)
    img.rgb[i] = static_cast<float>(std::sin(0.37 * static_cast<double>(i)) * 0.7 + 0.45);
  img.rgb[0] = -0.5f;
  img.rgb[1] = 1.5f;
  img.rgb[2] = std::numeric_limits<float>::quiet_NaN();
  img.rgb[3] = std::numeric_limits<float>::infinity();
  return img;
}

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() /
                     ("locus-image-" +
                      std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The chunk types of a PNG file, in order.
std::vector<std::string> chunks(const std::string& png) {
  std::vector<std::string> out;
  for (size_t at = 8; at + 12 <= png.size();) {
    const uint32_t n = get_be32(png.data() + at);
    out.push_back(png.substr(at + 4, 4));
    at += 12 + n;
  }
  return out;
}

TEST(ImageFiles, APngHoldsEachValuesCodeAndReadsBackExactly) {
  const Image img = test_image(37, 23);  // odd sizes: no row is a power of two
  const fs::path path = temp_dir() / "a.png";
  ASSERT_TRUE(write_image(path.string(), img).ok());
  auto back = read_image(path.string());
  ASSERT_TRUE(back.ok()) << back.status().message();
  ASSERT_EQ(back->width, 37);
  ASSERT_EQ(back->height, 23);
  for (size_t i = 0; i < img.rgb.size(); ++i) {
    ASSERT_EQ(std::lround(back->rgb[i] * 255.0f), quantize8(img.rgb[i])) << "sample " << i;
  }
  EXPECT_EQ(back->rgb[0], 0.0f);  // negative: 0
  EXPECT_EQ(back->rgb[1], 1.0f);  // over 1: 255
  EXPECT_EQ(back->rgb[2], 0.0f);  // NaN: 0
  EXPECT_EQ(back->rgb[3], 1.0f);  // +inf: 255
}

TEST(ImageFiles, APngIsTaggedLinearOrForDisplay) {
  const Image img = test_image(8, 4);
  const fs::path dir = temp_dir();
  ASSERT_TRUE(write_image((dir / "linear.png").string(), img).ok());
  ASSERT_TRUE(write_image((dir / "display.png").string(), img, true).ok());
  const std::string linear = file_bytes(dir / "linear.png");
  const std::string display = file_bytes(dir / "display.png");
  using V = std::vector<std::string>;
  EXPECT_EQ(chunks(linear), (V{"IHDR", "gAMA", "tEXt", "IDAT", "IEND"}));
  EXPECT_EQ(chunks(display), (V{"IHDR", "sRGB", "gAMA", "tEXt", "IDAT", "IEND"}));
  // gAMA 1.0 (100000) when linear, 1/2.2 (45455) beside sRGB.
  EXPECT_EQ(get_be32(linear.data() + linear.find("gAMA") + 4), 100000u);
  EXPECT_EQ(get_be32(display.data() + display.find("gAMA") + 4), 45455u);
  // The same samples either way.
  auto a = read_image((dir / "linear.png").string());
  auto b = read_image((dir / "display.png").string());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->rgb, b->rgb);
}

TEST(ImageFiles, ExrKeepsTheFloatsAndTiffTheir16BitCodes) {
  const fs::path dir = temp_dir();
  Image img = test_image(19, 11);
  img.rgb[2] = 2.0e6f;  // an EXR keeps what a PNG clamps (no NaN: compared with ==)
  img.rgb[3] = -3.25f;
  ASSERT_TRUE(write_image((dir / "a.exr").string(), img).ok());
  ASSERT_TRUE(write_image((dir / "a.tif").string(), img).ok());
  auto exr = read_image((dir / "a.exr").string());
  auto tif = read_image((dir / "a.tif").string());
  ASSERT_TRUE(exr.ok()) << exr.status().message();
  ASSERT_TRUE(tif.ok()) << tif.status().message();
  EXPECT_EQ(exr->rgb, img.rgb);
  for (size_t i = 0; i < img.rgb.size(); ++i) {
    ASSERT_EQ(std::lround(tif->rgb[i] * 65535.0f), quantize16(img.rgb[i])) << "sample " << i;
  }
}

TEST(ImageFiles, BadPathsAndFilesAreNamedInTheError) {
  const fs::path dir = temp_dir();
  const Image img = test_image(4, 4);
  Status s = write_image((dir / "a.bmp").string(), img);
  EXPECT_EQ(s.code(), Code::kInvalidArgument);
  EXPECT_NE(s.message().find("unsupported image type '.bmp'"), std::string::npos) << s.message();
  for (const char* name : {"no/such/dir/a.png", "no/such/dir/a.exr"}) {
    s = write_image((dir / name).string(), img);
    EXPECT_FALSE(s.ok()) << name;
    EXPECT_NE(s.message().find((dir / name).string()), std::string::npos) << s.message();
  }
  auto missing = read_image((dir / "missing.png").string());
  EXPECT_EQ(missing.status().code(), Code::kNotFound);
  EXPECT_NE(missing.status().message().find("missing.png"), std::string::npos);
  // A PNG cut short: refused as undecodable, not read as black.
  ASSERT_TRUE(write_image((dir / "whole.png").string(), img).ok());
  const std::string bytes = file_bytes(dir / "whole.png");
  std::ofstream(dir / "cut.png", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  auto cut = read_image((dir / "cut.png").string());
  EXPECT_FALSE(cut.ok());
  EXPECT_NE(cut.status().message().find("cut.png"), std::string::npos) << cut.status().message();
  // An EXR cut short, and one that is only the magic number: OpenEXR's
  // error, named, not a crash.
  ASSERT_TRUE(write_image((dir / "whole.exr").string(), img).ok());
  const std::string exr = file_bytes(dir / "whole.exr");
  std::ofstream(dir / "cut.exr", std::ios::binary) << exr.substr(0, exr.size() / 2);
  std::ofstream(dir / "magic.exr", std::ios::binary) << exr.substr(0, 4);
  for (const char* name : {"cut.exr", "magic.exr"}) {
    auto bad = read_image((dir / name).string());
    EXPECT_EQ(bad.status().code(), Code::kInvalidArgument) << name;
    EXPECT_NE(bad.status().message().find(name), std::string::npos) << bad.status().message();
  }
}

TEST(ImageFiles, AGoldenExrWrittenByOpenImageIOReadsAndWritesBackUnchanged) {
  // tests/golden/*.exr were written by OpenImageIO before Locus wrote its
  // EXRs with OpenEXR: both read them alike (render_test compares them).
  auto golden = read_image(std::string(LOCUS_SOURCE_DIR) + "/tests/golden/spheres.exr");
  ASSERT_TRUE(golden.ok()) << golden.status().message();
  const fs::path path = temp_dir() / "again.exr";
  ASSERT_TRUE(write_image(path.string(), *golden).ok());
  auto again = read_image(path.string());
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->width, golden->width);
  EXPECT_EQ(again->rgb, golden->rgb);
}

}  // namespace
}  // namespace locus
