// A band's cost counts on the wire and in the coordinator's band records
// (common/farm/band_codec.h encode_band_cost/decode_band_cost; issue #27
// item 5, docs/cost-map.md "On the farm"): they round-trip exactly, and no
// payload a worker can send crashes the decoder, makes it allocate more
// than the band needs or gives counts of another size.
#include <gtest/gtest.h>
#include <zstd.h>

#include <random>

#include "common/farm/band_codec.h"

namespace locus::farm {
namespace {

CostBuffer some_counts(int width, int y0, int y1, uint32_t seed) {
  CostBuffer c;
  c.reset(width, y0, y1);
  std::mt19937 rng(seed);
  for (PixelCost& p : c.pixels) {
    p.rays_eye = rng() % 3;
    p.rays_reflected = rng() % 5;
    p.rays_refracted = rng() % 2;
    p.rays_shadow = rng();  // every bit of the field travels
    p.tests_shadow_volume = rng() % 1000;
    p.traced = rng() % 2;
    p.traced_span = p.traced && rng() % 2;
  }
  return c;
}

void expect_same(const CostBuffer& a, const CostBuffer& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.y0, b.y0);
  ASSERT_EQ(a.y1, b.y1);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  for (size_t i = 0; i < a.pixels.size(); ++i) {
    const PixelCost &p = a.pixels[i], &q = b.pixels[i];
    ASSERT_EQ(p.rays_eye, q.rays_eye) << i;
    ASSERT_EQ(p.rays_reflected, q.rays_reflected) << i;
    ASSERT_EQ(p.rays_refracted, q.rays_refracted) << i;
    ASSERT_EQ(p.rays_shadow, q.rays_shadow) << i;
    ASSERT_EQ(p.tests_shadow_volume, q.tests_shadow_volume) << i;
    ASSERT_EQ(p.traced, q.traced) << i;
    ASSERT_EQ(p.traced_span, q.traced_span) << i;
  }
}

TEST(BandCostCodec, CountsRoundTripExactly) {
  for (const auto& [w, y0, y1] : {std::tuple{1, 0, 1}, {7, 3, 5}, {64, 10, 58}}) {
    const CostBuffer c = some_counts(w, y0, y1, static_cast<uint32_t>(w * 100 + y0));
    auto bytes = encode_band_cost(c);
    ASSERT_TRUE(bytes.ok()) << bytes.status().message();
    EXPECT_TRUE(check_band_cost(*bytes, static_cast<int64_t>(w) * (y1 - y0)).ok());
    auto back = decode_band_cost(*bytes, w, y0, y1);
    ASSERT_TRUE(back.ok()) << back.status().message();
    expect_same(c, *back);
    EXPECT_EQ(back->totals().rays_shadow, c.totals().rays_shadow);
  }
  // Mostly zeros, as most pixels of a render are: a few bytes a pixel.
  CostBuffer quiet;
  quiet.reset(256, 0, 64);
  quiet.pixels[100].rays_eye = 1;
  auto small = encode_band_cost(quiet);
  ASSERT_TRUE(small.ok());
  EXPECT_LT(small->size(), quiet.pixels.size() / 8);
  CostBuffer none;
  EXPECT_FALSE(encode_band_cost(none).ok());
}

TEST(BandCostCodec, MalformedPayloadsAreErrorsNamingTheProblem) {
  const CostBuffer c = some_counts(8, 0, 4, 7);
  const std::string good = *encode_band_cost(c);
  const auto message = [](const Result<CostBuffer>& r) {
    return r.ok() ? std::string("(decoded)") : r.status().message();
  };
  // Another band's size: refused by the size the frame says, before
  // anything is inflated.
  auto other = decode_band_cost(good, 8, 0, 5);
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.status().code(), Code::kInvalidArgument);
  EXPECT_NE(message(other).find("cost counts"), std::string::npos) << message(other);
  EXPECT_NE(message(other).find("expected"), std::string::npos) << message(other);
  EXPECT_FALSE(check_band_cost(good, 33).ok());
  // Not zstd, truncated, empty.
  EXPECT_NE(message(decode_band_cost("not zstd at all", 8, 0, 4)).find("not a zstd frame"),
            std::string::npos);
  EXPECT_FALSE(decode_band_cost(good.substr(0, good.size() - 3), 8, 0, 4).ok());
  EXPECT_FALSE(decode_band_cost("", 8, 0, 4).ok());
  // Sizes out of range: no band of no pixels, none beyond a band's bound.
  EXPECT_FALSE(decode_band_cost(good, 0, 0, 4).ok());
  EXPECT_FALSE(decode_band_cost(good, 8, 4, 4).ok());
  EXPECT_FALSE(check_band_cost(good, int64_t{1} << 40).ok());
  // A zstd bomb: a frame claiming far more than the band needs is refused
  // by its claim (a small band asked of a huge payload).
  std::string big(8 * 4 * 21 * 1000, '\0');
  std::string z(ZSTD_compressBound(big.size()), '\0');
  z.resize(ZSTD_compress(z.data(), z.size(), big.data(), big.size(), 1));
  EXPECT_FALSE(decode_band_cost(z, 8, 0, 4).ok());
  // Flags beyond the two known bits.
  std::string raw(32 * 21, '\0');
  raw[32 * 20 + 5] = 4;
  std::string zf(ZSTD_compressBound(raw.size()), '\0');
  zf.resize(ZSTD_compress(zf.data(), zf.size(), raw.data(), raw.size(), 1));
  auto flags = decode_band_cost(zf, 8, 0, 4);
  ASSERT_FALSE(flags.ok());
  EXPECT_NE(message(flags).find("pixel 5 has unknown flags 4"), std::string::npos)
      << message(flags);
  // Random damage never crashes and never yields another size.
  std::mt19937 rng(3);
  for (int i = 0; i < 2000; ++i) {
    std::string bad = good;
    for (int k = 0; k < 1 + static_cast<int>(rng() % 4); ++k)
      bad[rng() % bad.size()] = static_cast<char>(rng());
    auto r = decode_band_cost(bad, 8, 0, 4);
    if (r.ok()) {
      EXPECT_EQ(r->pixels.size(), 32u);
    }
  }
}

}  // namespace
}  // namespace locus::farm
