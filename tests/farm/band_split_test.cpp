// Cost-aware band splitting (common/farm/band_split.h; issue #9 item 4).
#include "common/farm/band_split.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "common/farm/band_codec.h"
#include "common/scene/scene_io.h"

namespace locus {
namespace {

double band_cost(const std::vector<double>& costs, int y0, int y1) {
  return std::accumulate(costs.begin() + y0, costs.begin() + y1, 0.0);
}

TEST(BandSplit, EqualCostsGiveEqualHeights) {
  const std::vector<double> costs(100, 3.0);
  const std::vector<int> e = split_rows_by_cost(costs, 4);
  EXPECT_EQ(e, (std::vector<int>{0, 25, 50, 75, 100}));
}

TEST(BandSplit, SkewedCostsAreBalancedAndEveryBandHasARow) {
  // Rows 40..59 cost 50x the rest: a mirror across the middle of a frame.
  std::vector<double> costs(100, 1.0);
  for (int y = 40; y < 60; ++y) costs[y] = 50.0;
  const double total = std::accumulate(costs.begin(), costs.end(), 0.0);
  const std::vector<int> e = split_rows_by_cost(costs, 8);
  ASSERT_EQ(e.size(), 9u);
  EXPECT_EQ(e.front(), 0);
  EXPECT_EQ(e.back(), 100);
  double worst = 0;
  for (int b = 0; b < 8; ++b) {
    ASSERT_LT(e[b], e[b + 1]);
    worst = std::max(worst, band_cost(costs, e[b], e[b + 1]));
  }
  // Within one row's cost of the ideal share; equal heights would give a
  // band of 12-13 rows at 50 each, 4.4x the mean.
  EXPECT_LE(worst, total / 8 + 50.0);
  // As many bands as rows: one row each, even with all the cost in one.
  std::vector<double> one(5, 0.0);
  one[2] = 1e9;
  EXPECT_EQ(split_rows_by_cost(one, 5), (std::vector<int>{0, 1, 2, 3, 4, 5}));
}

// An EXR job's edges on its blocks of 16 rows: the equal split's and a cost
// split's moved to the nearest block edge, every band keeping a block;
// more bands than blocks are left as they were.
TEST(BandSplit, EdgesOfAnExrJobMoveOntoItsBlocks) {
  EXPECT_EQ(align_band_edges(512, 32, {}), [] {
    std::vector<int> e;
    for (int y = 0; y <= 512; y += 16) e.push_back(y);
    return e;
  }());
  // 1080 rows in 32 bands: 33.75 rows each; 68 blocks, the last of 8 rows.
  const std::vector<int> a = align_band_edges(1080, 32, {});
  ASSERT_EQ(a.size(), 33u);
  EXPECT_EQ(a.front(), 0);
  EXPECT_EQ(a.back(), 1080);
  for (int i = 1; i < 32; ++i) {
    EXPECT_EQ(a[i] % 16, 0) << i;
    EXPECT_GT(a[i], a[i - 1]) << i;
    EXPECT_LE(std::abs(a[i] - 1080 * i / 32), 8) << i;  // the nearest block edge
  }
  // A cost split's edges crowded at the top: each band still gets a block.
  EXPECT_EQ(align_band_edges(70, 4, {0, 1, 2, 3, 70}), (std::vector<int>{0, 16, 32, 48, 70}));
  EXPECT_EQ(align_band_edges(70, 3, {0, 9, 60, 70}), (std::vector<int>{0, 16, 64, 70}));
  // Each aligned band holds a block, so its worker compresses its own.
  for (int i = 0; i < 32; ++i) EXPECT_TRUE(farm::holds_exr_block(a[i], a[i + 1], 1080)) << i;
  EXPECT_TRUE(farm::holds_exr_block(64, 70, 70));  // the frame's last block, of 6 rows
  EXPECT_TRUE(farm::holds_exr_block(60, 70, 70));  // ... from row 60
  EXPECT_FALSE(farm::holds_exr_block(60, 66, 70));
  EXPECT_FALSE(farm::holds_exr_block(1, 31, 70));
  EXPECT_TRUE(farm::holds_exr_block(0, 16, 70));
  // More bands than blocks (5 for 70 rows): as given.
  EXPECT_EQ(align_band_edges(70, 6, {}), std::vector<int>{});
  EXPECT_EQ(align_band_edges(70, 6, {0, 1, 2, 3, 4, 5, 70}),
            (std::vector<int>{0, 1, 2, 3, 4, 5, 70}));
}

TEST(BandSplit, ThePrePassRunsOnlyForFewBandsPerWorker) {
  EXPECT_TRUE(cost_split_pays(2, 1));
  EXPECT_TRUE(cost_split_pays(7, 1));
  EXPECT_FALSE(cost_split_pays(8, 1));
  EXPECT_TRUE(cost_split_pays(15, 2));
  EXPECT_FALSE(cost_split_pays(32, 2));  // `locus render --workers 2`'s default
  EXPECT_TRUE(cost_split_pays(64, 64));  // a band per worker
  EXPECT_TRUE(cost_split_pays(5, 0));    // no worker yet: as for one
  EXPECT_FALSE(cost_split_pays(8, 0));
  EXPECT_FALSE(cost_split_pays(1, 4));   // one band: nothing to split
}

TEST(BandSplit, PredictsMirrorRowsAsDearerAndIsDeterministic) {
  auto scene = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  scene->camera.width = 256;
  scene->camera.height = 256;
  RenderParams p;
  p.method = Method::kLocal;
  p.aa = 4;
  auto a = predict_row_costs(*scene, p, 1);
  auto b = predict_row_costs(*scene, p, 1);
  ASSERT_TRUE(a.ok()) << a.status().message();
  ASSERT_EQ(a->size(), 256u);
  EXPECT_EQ(*a, *b);
  // The pre-pass on three threads (rows side by side) counts the same.
  auto c = predict_row_costs(*scene, p, 3);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(*a, *c);
  // The image's top rows show only the floor far away (no mirror): the
  // dearest rows, through the mirror spheres, cost several times more.
  const auto [lo, hi] = std::minmax_element(a->begin(), a->end());
  EXPECT_GT(*lo, 0.0);
  EXPECT_GT(*hi, 3.0 * *lo);
  // A render's real cost per band follows: the band with the largest
  // predicted share is also among the slowest (checked by counts, not
  // clocks): its ray count exceeds the mean band's.
  const std::vector<int> eq{0, 64, 128, 192, 256};
  std::vector<double> predicted, rays;
  auto prepared = prepare_scene(*scene, p);
  ASSERT_TRUE(prepared.ok());
  for (int k = 0; k < 4; ++k) {
    predicted.push_back(band_cost(*a, eq[k], eq[k + 1]));
    const BandResult r = render_band(**prepared, Band{eq[k], eq[k + 1]}, p);
    rays.push_back(static_cast<double>(r.stats.rays_eye + r.stats.rays_reflected +
                                       r.stats.rays_refracted + r.stats.rays_shadow));
  }
  const int dearest = static_cast<int>(std::max_element(predicted.begin(), predicted.end()) -
                                       predicted.begin());
  EXPECT_GT(rays[dearest], std::accumulate(rays.begin(), rays.end(), 0.0) / 4);
}

}  // namespace
}  // namespace locus
