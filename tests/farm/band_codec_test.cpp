// Band encodings (common/farm/band_codec.h; issue #25 item 4): every
// encoding round-trips, frames written from decoded bands are the bytes of
// frames written from the renderer's floats, and no payload a worker can
// send makes the decoder crash, over-allocate or give pixels of another size.
#include "common/farm/band_codec.h"

#include <gtest/gtest.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "common/base/exr.h"
#include "common/base/image.h"
#include "common/render.h"
#include "common/scene/scene_io.h"

namespace locus::farm {
namespace {

namespace fs = std::filesystem;

constexpr BandEncoding kAll[] = {BandEncoding::kFloat32,     BandEncoding::kRgb8Zstd,
                                 BandEncoding::kRgb16Zstd,   BandEncoding::kFloat32Zstd,
                                 BandEncoding::kPng8Deflate, BandEncoding::kExrZip};

std::string name_of(BandEncoding e) { return std::string(label_name(kBandEncodingLabels, e)); }

// Values a renderer can give, and the edges of every quantisation: negative,
// above 1, infinities, NaN, signed zeros, subnormals, the halves between
// codes.
std::vector<float> awkward_floats(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.25f, 1.25f);
  const float specials[] = {0.0f,
                            -0.0f,
                            1.0f,
                            0.5f / 255.0f,
                            127.5f / 255.0f,
                            0.5f / 65535.0f,
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::quiet_NaN(),
                            std::numeric_limits<float>::denorm_min(),
                            std::numeric_limits<float>::max(),
                            1e30f};
  std::vector<float> v(n);
  for (size_t i = 0; i < n; ++i)
    v[i] = i % 7 == 0 ? specials[(i / 7) % std::size(specials)] : u(rng);
  return v;
}

TEST(BandCodec, EveryCodeDecodesToAFloatTheWriterMapsBackToIt) {
  // What makes the integer encodings lossless for the written file.
  for (int q = 0; q <= 255; ++q) ASSERT_EQ(quantize8(static_cast<float>(q) / 255.0f), q) << q;
  for (int q = 0; q <= 65535; ++q) ASSERT_EQ(quantize16(static_cast<float>(q) / 65535.0f), q) << q;
}

TEST(BandCodec, ChoosesTheEncodingOfTheWrittenFile) {
  EXPECT_EQ(band_encoding_for("out/shot_####.png"), BandEncoding::kRgb8Zstd);
  EXPECT_EQ(band_encoding_for("SHOT_0001.PNG"), BandEncoding::kRgb8Zstd);
  // A worker that offers png8+deflate gets it for PNG jobs, and only those.
  EXPECT_EQ(band_encoding_for("out/shot_####.png", true), BandEncoding::kPng8Deflate);
  EXPECT_EQ(band_encoding_for("a.tif", true), BandEncoding::kRgb16Zstd);
  EXPECT_EQ(band_encoding_for("a.exr", true), BandEncoding::kFloat32Zstd);
  // A worker that offers exr+zip gets it for EXR jobs, and only those.
  EXPECT_EQ(band_encoding_for("out/shot_####.exr", false, true), BandEncoding::kExrZip);
  EXPECT_EQ(band_encoding_for("a.png", false, true), BandEncoding::kRgb8Zstd);
  EXPECT_EQ(band_encoding_for("a.png", true, true), BandEncoding::kPng8Deflate);
  EXPECT_EQ(band_encoding_for("a.tif", true, true), BandEncoding::kRgb16Zstd);
  EXPECT_EQ(band_encoding_for("shot.mp4", true), BandEncoding::kFloat32);
  EXPECT_EQ(band_encoding_for("out/shot_####.exr"), BandEncoding::kFloat32Zstd);
  EXPECT_EQ(band_encoding_for("a.tif"), BandEncoding::kRgb16Zstd);
  EXPECT_EQ(band_encoding_for("a.tiff"), BandEncoding::kRgb16Zstd);
  // Nothing known of the file (a movie job has no bands): floats, as ever.
  EXPECT_EQ(band_encoding_for("shot.mp4"), BandEncoding::kFloat32);
  EXPECT_EQ(band_encoding_for(""), BandEncoding::kFloat32);
}

TEST(BandCodec, EveryEncodingRoundTrips) {
  const int width = 37, rows = 5;
  const std::vector<float> rgb = awkward_floats(static_cast<size_t>(width) * rows * 3, 25);
  for (BandEncoding e : kAll) {
    SCOPED_TRACE(name_of(e));
    auto enc = encode_band(e, width, rows, rgb);
    ASSERT_TRUE(enc.ok()) << enc.status().message();
    EXPECT_EQ(enc->encoding, e);
    EXPECT_EQ(enc->width, width);
    EXPECT_EQ(enc->rows, rows);
    auto dec = decode_band(*enc);
    ASSERT_TRUE(dec.ok()) << dec.status().message();
    ASSERT_EQ(dec->size(), rgb.size());
    for (size_t i = 0; i < rgb.size(); ++i) {
      if (e == BandEncoding::kFloat32 || e == BandEncoding::kFloat32Zstd ||
          e == BandEncoding::kExrZip) {
        // The floats' bits, NaN payloads and -0 included.
        ASSERT_EQ(std::bit_cast<uint32_t>((*dec)[i]), std::bit_cast<uint32_t>(rgb[i])) << i;
      } else if (e == BandEncoding::kRgb8Zstd || e == BandEncoding::kPng8Deflate) {
        ASSERT_EQ(quantize8((*dec)[i]), quantize8(rgb[i])) << i;
      } else {
        ASSERT_EQ(quantize16((*dec)[i]), quantize16(rgb[i])) << i;
      }
    }
    // Decoding is a function of the bytes: encoding the decoded floats again
    // gives the same payload (what the coordinator would store).
    auto again = encode_band(e, width, rows, *dec);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(again->bytes, enc->bytes);
  }
  // The uncompressed floats are 12 bytes a pixel.
  EXPECT_EQ(encode_band(BandEncoding::kFloat32, width, rows, rgb)->bytes.size(),
            static_cast<size_t>(width) * rows * 12);
}

TEST(BandCodec, EncodeRefusesAWrongSizeOrAnUnknownEncoding) {
  const std::vector<float> rgb(30, 0.5f);
  auto r = encode_band(BandEncoding::kRgb8Zstd, 4, 3, rgb);  // 36 floats needed
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  EXPECT_NE(r.status().message().find("4 x 3 pixels from 30 floats"), std::string::npos)
      << r.status().message();
  auto u = encode_band(static_cast<BandEncoding>(42), 10, 1, rgb);
  ASSERT_FALSE(u.ok());
  EXPECT_NE(u.status().message().find("unknown encoding 42"), std::string::npos);
}

// Configuration IV, as the farm's jobs render by default, on 2 threads.
RenderParams params_iv() {
  RenderParams p;
  p.method = Method::kLocal;
  p.aa = 4;
  p.threads = 2;
  return p;
}

// The paper's scene (d) at width x height, prepared with params_iv().
auto prepare_d(int width, int height) {
  auto scene = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json");
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  scene->camera.width = width;
  scene->camera.height = height;
  return prepare_scene(*scene, params_iv());
}

// A real scene rendered band by band, as workers do: the frames written from
// the decoded bands store the samples of the frames written from the
// floats (a PNG byte for byte), for each output format and its encoding.
TEST(BandCodec, FramesWrittenFromDecodedBandsAreBitIdentical) {
  const RenderParams p = params_iv();
  auto prepared = prepare_d(96, 64);
  ASSERT_TRUE(prepared.ok()) << prepared.status().message();
  const std::vector<int> edges{0, 7, 20, 41, 64};  // uneven bands, as a cost-aware split gives
  std::vector<BandResult> bands;
  Image floats(96, 64);
  for (size_t b = 0; b + 1 < edges.size(); ++b) {
    bands.push_back(render_band(**prepared, Band{edges[b], edges[b + 1]}, p));
    std::copy(bands.back().pixels.rgb.begin(), bands.back().pixels.rgb.end(),
              floats.pixel(0, edges[b]));
  }
  const fs::path dir = fs::path(::testing::TempDir()) / "band_codec_frames";
  fs::create_directories(dir);
  const auto file_bytes = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  };
  for (const char* ext : {".png", ".exr", ".tif"}) {
    SCOPED_TRACE(ext);
    const BandEncoding e = band_encoding_for(std::string("frame") + ext);
    ASSERT_NE(e, BandEncoding::kFloat32);
    Image decoded(96, 64);
    size_t wire = 0;
    for (size_t b = 0; b < bands.size(); ++b) {
      const int rows = edges[b + 1] - edges[b];
      auto enc = encode_band(e, 96, rows, bands[b].pixels.rgb);
      ASSERT_TRUE(enc.ok()) << enc.status().message();
      wire += enc->bytes.size();
      auto dec = decode_band(*enc);
      ASSERT_TRUE(dec.ok()) << dec.status().message();
      std::copy(dec->begin(), dec->end(), decoded.pixel(0, edges[b]));
    }
    const fs::path a = dir / (std::string("floats") + ext);
    const fs::path d = dir / (std::string("decoded") + ext);
    ASSERT_TRUE(write_image(a.string(), floats).ok());
    ASSERT_TRUE(write_image(d.string(), decoded).ok());
    // A PNG's bytes are its pixels'; TIFF and EXR files also carry the
    // second they were written (DateTime, capDate), so for those the
    // stored samples are compared, read back exactly (codes / 65535, or
    // the floats themselves).
    if (std::string(ext) == ".png") {
      const std::string fa = file_bytes(a);
      ASSERT_FALSE(fa.empty());
      EXPECT_EQ(fa, file_bytes(d));
    }
    auto ia = read_image(a.string());
    auto id = read_image(d.string());
    ASSERT_TRUE(ia.ok() && id.ok());
    EXPECT_EQ(ia->rgb, id->rgb);
    // Fewer bytes than the 12 a pixel of today's floats.
    EXPECT_LT(wire, static_cast<size_t>(96) * 64 * 12 / 2);
  }
}

EncodedBand valid_band(BandEncoding e, int width = 16, int rows = 4) {
  auto enc = encode_band(e, width, rows, awkward_floats(static_cast<size_t>(width) * rows * 3, 7));
  EXPECT_TRUE(enc.ok());
  return *enc;
}

// Refused by decode_band, and by check_band (the coordinator's check on
// arrival) with the same words.
void expect_refused(const EncodedBand& band, const std::string& words) {
  auto r = decode_band(band);
  ASSERT_FALSE(r.ok()) << "decoded " << r->size() << " floats";
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().message();
  const Status checked = check_band(band);
  EXPECT_EQ(checked.code(), r.status().code());
  EXPECT_EQ(checked.message(), r.status().message());
}

// png8+deflate (band_codec.h): a PNG joined from the bands' deflate streams
// (png_from_bands, as the coordinator writes a PNG job's frames) holds the
// pixels write_image writes from the renderer's floats, for any split: one
// band, uneven bands, a band per row.
TEST(BandCodec, PngFramesJoinedFromDeflatedBandsHoldTheRenderersPixels) {
  const int width = 96, height = 64;
  const RenderParams p = params_iv();
  auto prepared = prepare_d(width, height);
  ASSERT_TRUE(prepared.ok()) << prepared.status().message();
  const BandResult whole = render_band(**prepared, Band{0, height}, p);
  const fs::path dir = fs::path(::testing::TempDir()) / "band_codec_png";
  fs::create_directories(dir);
  Image floats(width, height);
  floats.rgb = whole.pixels.rgb;
  ASSERT_TRUE(write_image((dir / "written.png").string(), floats).ok());
  auto expected = read_image((dir / "written.png").string());
  ASSERT_TRUE(expected.ok());
  std::vector<int> per_row;
  for (int y = 0; y <= height; ++y) per_row.push_back(y);
  for (const std::vector<int>& edges :
       {std::vector<int>{0, height}, std::vector<int>{0, 7, 20, 41, 64}, per_row}) {
    SCOPED_TRACE(std::to_string(edges.size() - 1) + " bands");
    std::vector<EncodedBand> bands;
    size_t wire = 0;
    for (size_t b = 0; b + 1 < edges.size(); ++b) {
      const size_t from = static_cast<size_t>(edges[b]) * width * 3;
      const size_t to = static_cast<size_t>(edges[b + 1]) * width * 3;
      const std::vector<float> rgb(whole.pixels.rgb.begin() + from,
                                   whole.pixels.rgb.begin() + to);
      auto enc = encode_band(BandEncoding::kPng8Deflate, width, edges[b + 1] - edges[b], rgb);
      ASSERT_TRUE(enc.ok()) << enc.status().message();
      ASSERT_TRUE(check_band(*enc).ok());  // what the coordinator checks on arrival
      wire += enc->bytes.size();
      bands.push_back(std::move(*enc));
    }
    auto png = png_from_bands(width, height, bands);
    ASSERT_TRUE(png.ok()) << png.status().message();
    const fs::path joined = dir / ("joined_" + std::to_string(bands.size()) + ".png");
    std::ofstream(joined, std::ios::binary) << *png;
    auto got = read_image(joined.string());
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->width, width);
    EXPECT_EQ(got->height, height);
    EXPECT_EQ(got->rgb, expected->rgb);
    // At most the 3 bytes a pixel of the codes (and a filter byte a row).
    EXPECT_LT(wire, static_cast<size_t>(width) * height * 3);
  }
}

// exr+zip (band_codec.h): an EXR joined from the bands' blocks
// (exr_blocks_from_bands, as the coordinator writes an EXR job's frames)
// holds the renderer's floats, for any split: one band, bands on the
// blocks' edges, uneven bands, a band per row; and the blocks are the same
// bytes whichever bands they came in. 70 rows: a last block of 6.
TEST(BandCodec, ExrFramesJoinedFromZippedBandsHoldTheRenderersFloats) {
  const int width = 96, height = 70;
  const RenderParams p = params_iv();
  auto prepared = prepare_d(width, height);
  ASSERT_TRUE(prepared.ok()) << prepared.status().message();
  const BandResult whole = render_band(**prepared, Band{0, height}, p);
  const fs::path dir = fs::path(::testing::TempDir()) / "band_codec_exr";
  fs::create_directories(dir);
  std::vector<int> per_row;
  for (int y = 0; y <= height; ++y) per_row.push_back(y);
  std::vector<std::string> first_blocks;
  // How many of the 5 blocks no band holds whole (compressed from edge
  // rows), for each split.
  const std::vector<size_t> made = {0, 0, 4, 5};
  size_t split = 0;
  for (const std::vector<int>& edges :
       {std::vector<int>{0, height}, std::vector<int>{0, 16, 48, 64, 70},
        std::vector<int>{0, 7, 20, 41, 66, 70}, per_row}) {
    SCOPED_TRACE(std::to_string(edges.size() - 1) + " bands");
    std::vector<EncodedBand> bands;
    std::vector<int> y0s;
    size_t wire = 0;
    for (size_t b = 0; b + 1 < edges.size(); ++b) {
      const size_t from = static_cast<size_t>(edges[b]) * width * 3;
      const size_t to = static_cast<size_t>(edges[b + 1]) * width * 3;
      const std::vector<float> rgb(whole.pixels.rgb.begin() + from, whole.pixels.rgb.begin() + to);
      auto enc =
          encode_band(BandEncoding::kExrZip, width, edges[b + 1] - edges[b], rgb, edges[b], height);
      ASSERT_TRUE(enc.ok()) << enc.status().message();
      ASSERT_TRUE(check_band(*enc).ok());  // what the coordinator checks on arrival
      auto dec = decode_band(*enc);
      ASSERT_TRUE(dec.ok()) << dec.status().message();
      EXPECT_EQ(*dec, rgb);
      wire += enc->bytes.size();
      bands.push_back(std::move(*enc));
      y0s.push_back(edges[b]);
    }
    auto blocks = exr_blocks_from_bands(width, height, y0s, bands);
    ASSERT_TRUE(blocks.ok()) << blocks.status().message();
    ASSERT_EQ(blocks->blocks.size(), 5u);
    const std::vector<std::string> bytes(blocks->blocks.begin(), blocks->blocks.end());
    if (first_blocks.empty()) first_blocks = bytes;
    EXPECT_EQ(bytes, first_blocks);
    // A block a band holds whole is a view of that band's bytes, not a
    // copy; the others are the ones made here.
    EXPECT_EQ(blocks->made.size(), made[split]);
    size_t in_bands = 0, in_made = 0;
    for (const std::string_view v : blocks->blocks) {
      const auto inside = [&](const std::string& s) {
        return v.data() >= s.data() && v.data() + v.size() <= s.data() + s.size();
      };
      in_bands += std::any_of(bands.begin(), bands.end(),
                              [&](const EncodedBand& b) { return inside(b.bytes); });
      in_made += std::any_of(blocks->made.begin(), blocks->made.end(), inside);
    }
    EXPECT_EQ(in_bands, 5u - made[split]);
    EXPECT_EQ(in_made, made[split]);
    ++split;
    const fs::path joined = dir / ("joined_" + std::to_string(bands.size()) + ".exr");
    ASSERT_TRUE(write_exr_blocks(joined.string(), width, height, blocks->blocks).ok());
    auto got = read_image(joined.string());
    ASSERT_TRUE(got.ok()) << got.status().message();
    EXPECT_EQ(got->width, width);
    EXPECT_EQ(got->height, height);
    EXPECT_EQ(got->rgb, whole.pixels.rgb);
    // Fewer bytes than the floats (a band per row: all of them float32+zstd).
    EXPECT_LT(wire, static_cast<size_t>(width) * height * 12);
  }
}

// What exr_blocks_from_bands cannot join, and payloads that are not an
// exr+zip band's, are refused naming the problem.
TEST(BandCodec, ExrZipRefusesBandsThatDoNotFit) {
  const int width = 8;
  // Smooth rows, whose blocks compress (a damaged stream cannot pass for
  // a block kept as laid out).
  const auto smooth = [](int rows) {
    std::vector<float> v(static_cast<size_t>(width) * rows * 3);
    for (size_t i = 0; i < v.size(); ++i) v[i] = 0.25f + 0.001f * static_cast<float>(i % 24);
    return v;
  };
  const auto band = [&](int y0, int rows, int height) {
    auto enc = encode_band(BandEncoding::kExrZip, width, rows, smooth(rows), y0, height);
    EXPECT_TRUE(enc.ok()) << enc.status().message();
    return *enc;
  };
  // Rows 0-19 and 20-39 of a frame of 40: block 1 (rows 16-31) is across.
  const EncodedBand top = band(0, 20, 40), bottom = band(20, 20, 40);
  ASSERT_TRUE(exr_blocks_from_bands(width, 40, {0, 20}, {top, bottom}).ok());
  const auto refused = [&](const std::vector<int>& y0s, const std::vector<EncodedBand>& bands,
                           int height, const std::string& words) {
    auto r = exr_blocks_from_bands(width, height, y0s, bands);
    ASSERT_FALSE(r.ok()) << words;
    EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
    EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().message();
  };
  // Its rows somewhere else than the band encoded them for.
  refused({0, 20}, {band(0, 20, 40), band(4, 20, 44)}, 40,
          "band 1: its blocks are not where rows 20 to 39 put them");
  refused({0, 20}, {top, valid_band(BandEncoding::kFloat32Zstd, width, 20)}, 40,
          "band 1 is not an exr+zip band 8 pixels wide from row 20");
  refused({0, 20}, {top, band(20, 10, 30)}, 40, "the bands hold 30 rows of a frame of 40");
  refused({0, 21}, {top, bottom}, 40, "band 1 is not an exr+zip band 8 pixels wide from row 20");
  refused({0}, {top, bottom}, 40, "a first row for each band");
  // Encoding rows outside the frame.
  auto outside = encode_band(BandEncoding::kExrZip, width, 4, std::vector<float>(96, 0.5f), 38, 40);
  ASSERT_FALSE(outside.ok());
  EXPECT_NE(outside.status().message().find("rows 38 to 41 of a frame of 40 rows"),
            std::string::npos)
      << outside.status().message();
  // Payloads: a middle band is one whole block between edges of 2 rows.
  const EncodedBand mid = band(14, 20, 40);  // head 2 (14-15), block 16-31, tail 2 (32-33)
  ASSERT_TRUE(check_band(mid).ok());
  const auto with = [&](size_t at, const std::string& bytes, size_t replace = 4) {
    EncodedBand b = mid;
    b.bytes.replace(at, replace, bytes);
    return b;
  };
  const auto be32 = [](uint32_t v) {
    std::string s;
    for (int sh = 24; sh >= 0; sh -= 8) s.push_back(static_cast<char>((v >> sh) & 0xff));
    return s;
  };
  expect_refused(with(0, be32(99)), "its rows' layout is out of range");
  expect_refused(with(12, be32(0)), "block 0 of 0 rows");
  expect_refused(with(12, be32(17)), "block 0 of 17 rows");
  // Only the frame's last block may be short, and nothing follows it.
  expect_refused(with(12, be32(15)), "block 0 of 15 rows");
  expect_refused(with(16, be32(static_cast<uint32_t>(mid.bytes.size()))),
                 "the bytes end inside a part");
  EncodedBand extra = mid;
  extra.bytes.push_back('x');
  expect_refused(extra, "bytes after the last part");
  // The block's data damaged: not a ZIP block of its rows.
  EncodedBand damaged = mid;
  for (size_t i = 20; i < 40; ++i) damaged.bytes[i] = static_cast<char>(0xA5);
  expect_refused(damaged, "exr+zip band of 8 x 20 pixels, block 0: not a ZIP block of 16 rows");
  // Edge rows whose float32+zstd bytes are not a zstd frame.
  const size_t tail_bytes =
      encode_band(BandEncoding::kFloat32Zstd, width, 2, smooth(2))->bytes.size();
  expect_refused(with(mid.bytes.size() - tail_bytes, "XXXX"),
                 "exr+zip band of 8 x 20 pixels, tail: float32+zstd band of 8 x 2 pixels: the "
                 "payload is not a zstd frame");
}

// The payload of a png8+deflate band from `raw` (each row's filter byte and
// bytes), its stream ended by `flush`, its adler-32 plus `adler_delta`.
std::string png8_payload(const std::string& raw, int flush, uint32_t adler_delta = 0) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 1, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string stream(raw.size() + 256, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
  z.avail_in = static_cast<uInt>(raw.size());
  z.next_out = reinterpret_cast<Bytef*>(stream.data());
  z.avail_out = static_cast<uInt>(stream.size());
  EXPECT_NE(deflate(&z, flush), Z_STREAM_ERROR);
  stream.resize(z.total_out);
  deflateEnd(&z);
  const uint32_t a =
      static_cast<uint32_t>(adler32(1, reinterpret_cast<const Bytef*>(raw.data()),
                                    static_cast<uInt>(raw.size()))) + adler_delta;
  std::string out;
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((a >> s) & 0xff));
  return out + stream;
}

// 4 x 3 pixels: each row a filter byte and 12 bytes.
std::string rows_with_filters(unsigned char f0, unsigned char f1, unsigned char f2) {
  std::string raw;
  for (unsigned char f : {f0, f1, f2}) {
    raw.push_back(static_cast<char>(f));
    for (int i = 0; i < 12; ++i) raw.push_back(static_cast<char>(f * 40 + i * 7));
  }
  return raw;
}

// What png_from_bands cannot join is refused on arrival, naming it: a first
// row that looks up (into the previous band, another worker's), a stream
// that ends the frame's, bytes after the rows, a wrong checksum, an unknown
// filter.
TEST(BandCodec, Png8DeflateRefusesBandsThatCannotBeJoined) {
  const auto band = [](const std::string& payload) {
    return EncodedBand{BandEncoding::kPng8Deflate, 4, 3, payload};
  };
  // Every filter inside the band is read (PNG specification, 9.2).
  for (unsigned char f : {0, 1, 2, 3, 4}) {
    auto ok = decode_band(band(png8_payload(rows_with_filters(f < 2 ? f : 1, f, f), Z_SYNC_FLUSH)));
    ASSERT_TRUE(ok.ok()) << int{f} << ": " << ok.status().message();
    EXPECT_EQ(ok->size(), 36u);
  }
  expect_refused(band(png8_payload(rows_with_filters(2, 2, 2), Z_SYNC_FLUSH)),
                 "row 0 has filter 2 (the first row: 0 or 1)");
  expect_refused(band(png8_payload(rows_with_filters(1, 2, 5), Z_SYNC_FLUSH)),
                 "row 2 has filter 5 (0 to 4)");
  expect_refused(band(png8_payload(rows_with_filters(1, 2, 2), Z_FINISH)),
                 "ends with the last block");
  expect_refused(band(png8_payload(rows_with_filters(1, 2, 2), Z_SYNC_FLUSH, 1)),
                 "do not match their adler-32");
  const std::string good = png8_payload(rows_with_filters(1, 2, 2), Z_SYNC_FLUSH);
  const std::string again = png8_payload(rows_with_filters(1, 2, 2), Z_SYNC_FLUSH);
  expect_refused(band(good + again.substr(4)), "holds more than 39 bytes, expected 39");
  expect_refused(band(good.substr(0, 3)), "no adler-32");
  // A band of another encoding, width or height is not joined.
  const EncodedBand b = band(good);
  EXPECT_TRUE(png_from_bands(4, 6, {b, b}).ok());
  EncodedBand zstd = valid_band(BandEncoding::kRgb8Zstd, 4, 3);
  for (const auto& [bands, words] :
       {std::pair{std::vector<EncodedBand>{b, zstd}, "band 1 is not a png8+deflate band 4 pixels"},
        std::pair{std::vector<EncodedBand>{b, valid_band(BandEncoding::kPng8Deflate, 5, 3)},
                  "band 1 is not a png8+deflate band 4 pixels"},
        std::pair{std::vector<EncodedBand>{b}, "the bands hold 3 rows of a frame of 6"}}) {
    auto r = png_from_bands(4, 6, bands);
    ASSERT_FALSE(r.ok()) << words;
    EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
    EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().message();
  }
}

TEST(BandCodec, MalformedPayloadsAreErrorsNamingTheProblem) {
  for (BandEncoding e : kAll) {
    SCOPED_TRACE(name_of(e));
    EncodedBand b = valid_band(e);
    // Truncated: a byte short, half, nothing.
    for (size_t keep : {b.bytes.size() - 1, b.bytes.size() / 2, size_t{0}}) {
      EncodedBand t = b;
      t.bytes.resize(keep);
      auto r = decode_band(t);
      ASSERT_FALSE(r.ok()) << keep;
      EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
      EXPECT_NE(r.status().message().find(name_of(e) + " band of 16 x 4 pixels"), std::string::npos)
          << r.status().message();
    }
    // The right bytes for another size than the one declared.
    EncodedBand w = b;
    w.rows = 5;
    expect_refused(w, e == BandEncoding::kFloat32 ? "768 bytes, expected 960" : "expected");
    // Sizes out of range: none, negative, or more than any band.
    for (auto [width, rows] : {std::pair{0, 4}, std::pair{16, -1}, std::pair{65536, 65536},
                               std::pair{1 << 30, 1 << 30}}) {
      EncodedBand s = b;
      s.width = width;
      s.rows = rows;
      expect_refused(s, "out of range");
    }
  }
  // Trailing bytes after the float32 payload; a zstd frame with garbage after it.
  EncodedBand f = valid_band(BandEncoding::kFloat32);
  f.bytes.push_back('x');
  expect_refused(f, "769 bytes, expected 768");
  EncodedBand z = valid_band(BandEncoding::kFloat32Zstd);
  z.bytes.append("garbage");
  expect_refused(z, "corrupt or truncated");
  // Not zstd at all.
  EncodedBand nz = valid_band(BandEncoding::kRgb8Zstd);
  nz.bytes = std::string(nz.bytes.size(), 'A');
  expect_refused(nz, "not a zstd frame");
}

TEST(BandCodec, AnUnknownEncodingIsAnError) {
  EncodedBand b = valid_band(BandEncoding::kRgb8Zstd);
  b.encoding = static_cast<BandEncoding>(7);
  expect_refused(b, "unknown encoding 7");
}

// zstd frames that would make the coordinator allocate or write more than
// the band: the decoder trusts neither the frame's claim nor its content.
TEST(BandCodec, ZstdBombsAreRefusedWithinTheBandsSize) {
  const int width = 16, rows = 4;
  const size_t expected = static_cast<size_t>(width) * rows * 3;  // rgb8: one byte a sample
  const auto compress = [](const std::string& raw) {
    std::string z(ZSTD_compressBound(raw.size()), '\0');
    z.resize(ZSTD_compress(z.data(), z.size(), raw.data(), raw.size(), 1));
    return z;
  };
  // 256 MiB of zeros in a few kilobytes, declared as a 16 x 4 band.
  {
    EncodedBand b{BandEncoding::kRgb8Zstd, width, rows, compress(std::string(256u << 20, '\0'))};
    EXPECT_LT(b.bytes.size(), 64u << 10);
    expect_refused(b, "holds 268435456 bytes, expected 192");
  }
  // The same claim but a band big enough to pass the claim check is out of
  // range before any allocation.
  {
    EncodedBand b{BandEncoding::kFloat32Zstd, 8192, 2048, compress(std::string(1u << 20, '\0'))};
    expect_refused(b, "out of range");
  }
  // A frame that does not say its size (streamed).
  {
    std::string raw(expected, '\1');
    std::string z(ZSTD_compressBound(raw.size()) + 64, '\0');
    ZSTD_CCtx* cctx = ZSTD_createCCtx();
    ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 0);
    ZSTD_outBuffer out{z.data(), z.size(), 0};
    ZSTD_inBuffer in{raw.data(), raw.size(), 0};
    ASSERT_EQ(ZSTD_compressStream2(cctx, &out, &in, ZSTD_e_end), 0u);
    ZSTD_freeCCtx(cctx);
    z.resize(out.pos);
    ASSERT_EQ(ZSTD_getFrameContentSize(z.data(), z.size()), ZSTD_CONTENTSIZE_UNKNOWN);
    expect_refused(EncodedBand{BandEncoding::kRgb8Zstd, width, rows, z},
                   "not a zstd frame with its size");
  }
  // A first frame of the right size followed by a second one of 64 MiB: the
  // decompression stops at the band's size.
  {
    const std::string z =
        compress(std::string(expected, '\2')) + compress(std::string(64u << 20, '\3'));
    expect_refused(EncodedBand{BandEncoding::kRgb8Zstd, width, rows, z}, "corrupt or truncated");
  }
}

// Random damage to valid payloads: an error or pixels of the declared size,
// never a crash (the coordinator fuzzer, tests/fuzz/, reaches the same code
// through CompleteBand).
TEST(BandCodec, DamagedPayloadsNeverCrash) {
  std::mt19937 rng(2501);
  for (BandEncoding e : kAll) {
    const EncodedBand good = valid_band(e, 23, 3);
    for (int trial = 0; trial < 2000; ++trial) {
      EncodedBand b = good;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < flips && !b.bytes.empty(); ++k) {
        b.bytes[rng() % b.bytes.size()] ^= static_cast<char>(1 + rng() % 255);
      }
      if (rng() % 4 == 0) b.bytes.resize(rng() % (b.bytes.size() + 1));
      auto r = decode_band(b);
      // The check on arrival says what decoding says, word for word.
      const Status checked = check_band(b);
      ASSERT_EQ(checked.message(), r.status().message());
      if (r.ok()) {
        ASSERT_TRUE(checked.ok());
        ASSERT_EQ(r->size(), static_cast<size_t>(23) * 3 * 3);
      } else {
        ASSERT_EQ(r.status().code(), Code::kInvalidArgument);
        ASSERT_EQ(checked.code(), Code::kInvalidArgument);
      }
    }
  }
}

}  // namespace
}  // namespace locus::farm
