// Cancelling a band (render_band's flag; issue #23 item 5): a band whose
// lease was taken back must free its worker within a row, for every row
// loop, even when one row hangs inside the renderer; without a cancel the
// row hook sees each row once and the pixels are those of a plain render.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>

#include "common/render.h"

namespace locus {
namespace {

Scene test_scene() {
  Scene s;
  s.has_camera = true;
  s.camera.from = Vec3(0, 0, 5);
  s.camera.at = Vec3(0, 0, 0);
  s.camera.up = Vec3(0, 1, 0);
  s.camera.angle = 30;
  s.camera.width = 24;
  s.camera.height = 40;
  s.background = Color(0.1, 0.2, 0.3);
  s.lights.push_back(Light{Vec3(2, 3, 5), std::nullopt});
  Material m;
  m.color = Color(1.0, 0.5, 0.25);
  m.kd = 0.8;
  s.materials.push_back(m);
  Object o;
  o.shape = Sphere{Vec3(0), 1.0};
  s.objects.push_back(o);
  return s;
}

// The three row loops of render_band: multi-scanned, point-sampled local,
// ray traced.
std::vector<RenderParams> every_row_loop() {
  RenderParams multiscan, local, raytrace;
  multiscan.method = local.method = Method::kLocal;
  multiscan.aa = 4;
  raytrace.method = Method::kRaytrace;
  raytrace.spp = 2;
  for (RenderParams* p : {&multiscan, &local, &raytrace}) p->threads = 2;
  return {multiscan, local, raytrace};
}

struct HookGuard {
  explicit HookGuard(std::function<void(int)> hook) { set_row_hook_for_test(std::move(hook)); }
  ~HookGuard() { set_row_hook_for_test({}); }
};

TEST(RenderCancel, WithoutCancelEveryRowOnceAndTheSamePixels) {
  const Scene s = test_scene();
  for (const RenderParams& p : every_row_loop()) {
    auto ps = prepare_scene(s, p);
    ASSERT_TRUE(ps.ok()) << ps.status().message();
    const BandResult plain = render_band(**ps, Band{0, 40}, p);
    std::mutex mu;
    std::multiset<int> rows;
    HookGuard guard([&](int row) {
      std::lock_guard lk(mu);
      rows.insert(row);
    });
    std::atomic<bool> cancel{false};
    const BandResult hooked = render_band(**ps, Band{5, 33}, p, &cancel);
    EXPECT_FALSE(hooked.cancelled);
    ASSERT_EQ(rows.size(), 28u) << "aa " << p.aa;
    for (int y = 5; y < 33; ++y) EXPECT_EQ(rows.count(y), 1u) << "row " << y << " aa " << p.aa;
    const size_t row_floats = static_cast<size_t>(s.camera.width) * 3;
    ASSERT_EQ(hooked.pixels.rgb.size(), 28 * row_floats);
    EXPECT_TRUE(std::equal(hooked.pixels.rgb.begin(), hooked.pixels.rgb.end(),
                           plain.pixels.rgb.begin() + 5 * row_floats))
        << "aa " << p.aa;
  }
}

TEST(RenderCancel, StopsWithinARowPerThread) {
  const Scene s = test_scene();
  for (const RenderParams& p : every_row_loop()) {
    auto ps = prepare_scene(s, p);
    ASSERT_TRUE(ps.ok()) << ps.status().message();
    std::atomic<bool> cancel{false};
    std::atomic<int> rows_after{0};
    HookGuard guard([&](int row) {
      if (cancel.load()) ++rows_after;
      if (row == 12) cancel.store(true);
    });
    const BandResult r = render_band(**ps, Band{0, 40}, p, &cancel);
    EXPECT_TRUE(r.cancelled) << "aa " << p.aa;
    // Each of the 2 threads asks at most once more after the flag is set.
    EXPECT_LE(rows_after.load(), p.threads) << "aa " << p.aa;
  }
}

TEST(RenderCancel, AHungRowStillLetsTheBandGo) {
  const Scene s = test_scene();
  for (const RenderParams& p : every_row_loop()) {
    auto ps = prepare_scene(s, p);
    ASSERT_TRUE(ps.ok()) << ps.status().message();
    std::atomic<bool> cancel{false};
    std::atomic<bool> hung{false};
    // Row 7 hangs (as a renderer stuck in one row would) until the band is
    // cancelled from outside; the other rows go on meanwhile.
    HookGuard guard([&](int row) {
      if (row != 7) return;
      hung.store(true);
      while (!cancel.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    });
    std::thread canceller([&] {
      while (!hung.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      cancel.store(true);
    });
    const BandResult r = render_band(**ps, Band{0, 40}, p, &cancel);
    canceller.join();
    EXPECT_TRUE(hung.load());
    EXPECT_TRUE(r.cancelled) << "aa " << p.aa;
  }
}

}  // namespace
}  // namespace locus
