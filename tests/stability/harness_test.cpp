// The checks of the stability suite (stability.h) are not vacuous: defects
// injected into a good render are found, and the render itself passes.
#include <gtest/gtest.h>

#include <limits>

#include "tests/stability/stability.h"

namespace locus {
namespace stability {
namespace {

TEST(StabilityHarness, FindsInjectedNaNSpecklesAndCracks) {
  Scene s = camera_scene(Vec3(2, 3, 6), Vec3(0, 0.5, 0), 45, 48, 48);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2))};
  s.lights = {Light{Vec3(3, 6, 4), std::nullopt}};
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(box(Vec3(-1, 0, -1), Vec3(1, 1.2, 0.5), 1));
  Scene s_bg = s;
  s_bg.background += Color(1.0);
  ModeResult ref, iv;
  ref.params = params(Method::kRaytrace, Boxes::kEyeShadow, 0, kRefSpp);
  iv.params = params(Method::kLocal, Boxes::kEyeShadow, kAa, 1);
  for (ModeResult* m : {&ref, &iv}) {
    m->img = render_or_fail(s, m->params, "harness");
    m->img_bg = render_or_fail(s_bg, m->params, "harness");
  }
  auto ps = prepare_scene(s, params(Method::kRaytrace, Boxes::kEyeShadow, 0, 1));
  ASSERT_TRUE(ps.ok());
  auto in_pixel = [&](int x, int y) { return range_in_pixel(**ps, x, y); };
  // The render is clean.
  EXPECT_EQ(count_nonfinite(iv.img), 0);
  EXPECT_EQ(count_speckles(iv.img, ref.img, 0.2, in_pixel), 0);
  EXPECT_EQ(count_cracks(iv, ref, 0.02), 0);
  // Pixel (30, 40) lies on the floor, far from any edge (the floor fills
  // the bottom of the image).
  ASSERT_LT(range3(ref.img, 30, 40), 0.05);
  ModeResult bad = iv;
  bad.img.pixel(30, 40)[1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(count_nonfinite(bad.img), 1);
  bad = iv;
  bad.img.pixel(30, 40)[0] += 0.3f;
  int sx = -1, sy = -1;
  EXPECT_EQ(count_speckles(bad.img, ref.img, 0.2, in_pixel, &sx, &sy), 1);
  EXPECT_EQ(sx, 30);
  EXPECT_EQ(sy, 40);
  // A crack: the pixel sees 5% background.
  bad = iv;
  for (int c = 0; c < 3; ++c) bad.img_bg.pixel(30, 40)[c] += 0.05f;
  EXPECT_EQ(count_cracks(bad, ref, 0.02), 1);
}

}  // namespace
}  // namespace stability
}  // namespace locus
