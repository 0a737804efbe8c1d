// The worker's rendering logic without a network (worker/band_renderer.h):
// bands of one frame share one prepared scene and stitch into the
// single-process image; bad bands and unknown scenes are refused.
#include "tests/farm_fixture.h"

namespace locus::farm {
namespace {
using namespace testing_farm;

TEST(BandRenderer, RendersBandsOfOneFramePreparingOnce) {
  auto scene = load_scene(kSpheres);
  ASSERT_TRUE(scene.ok());
  BandRenderer renderer(1);
  ASSERT_TRUE(renderer.add_scene("h", scene_to_proto(*scene), "spheres").ok());
  BandLease t;
  t.scene_hash = "h";
  t.frame = 1;
  t.width = 32;
  t.height = 24;
  t.frame_first = t.frame_last = 1;
  std::vector<float> stitched;
  for (int b = 0; b < 3; ++b) {
    t.y0 = b * 8;
    t.y1 = b * 8 + 8;
    auto out = renderer.render(t);
    ASSERT_TRUE(out.ok()) << out.status().message();
    EXPECT_EQ(out->rgb.size(), 32u * 8 * 3);
    stitched.insert(stitched.end(), out->rgb.begin(), out->rgb.end());
  }
  EXPECT_EQ(renderer.prepares(), 1);
  const Scene s = frame_scene(*scene, 32, 24, 1, 1, 1, 0);
  auto whole = render_image(s, *to_render_params(RenderSettings(), 1));
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(stitched, whole->pixels.rgb);

  t.y1 = 25;  // past the frame
  EXPECT_EQ(renderer.render(t).status().code(), Code::kInvalidArgument);
  t.scene_hash = "other";
  EXPECT_EQ(renderer.render(t).status().code(), Code::kFailedPrecondition);
}

// An orbit's frames: each prepared once, every one after the first on the
// first's geometry; each stitched frame as the single-process image. A
// geometry is let go with the last frame kept of its scene.
TEST(BandRenderer, FramesOfAnOrbitShareTheirGeometry) {
  auto scene = load_scene(kSpheres);
  ASSERT_TRUE(scene.ok());
  auto other = load_scene(std::string(LOCUS_SHARED_DIR) + "/spd/s1/tetra.nff");
  ASSERT_TRUE(other.ok());
  BandRenderer renderer(1, "", 4, /*max_prepared=*/1);
  ASSERT_TRUE(renderer.add_scene("h", scene_to_proto(*scene), "spheres").ok());
  ASSERT_TRUE(renderer.add_scene("t", scene_to_proto(*other), "tetra").ok());
  BandLease t;
  t.width = 32;
  t.height = 24;
  t.frame_first = 1;
  t.frame_last = 3;
  t.orbit_degrees = 60;
  auto frame = [&](const std::string& hash, int f) {
    t.scene_hash = hash;
    t.frame = f;
    std::vector<float> stitched;
    for (int b = 0; b < 2; ++b) {
      t.y0 = b * 12;
      t.y1 = b * 12 + 12;
      auto out = renderer.render(t);
      EXPECT_TRUE(out.ok()) << out.status().message();
      if (out.ok()) stitched.insert(stitched.end(), out->rgb.begin(), out->rgb.end());
    }
    return stitched;
  };
  const RenderParams params = *to_render_params(RenderSettings(), 1);
  for (int f = 1; f <= 3; ++f) {
    auto whole = render_image(frame_scene(*scene, 32, 24, f, 1, 3, 60), params);
    ASSERT_TRUE(whole.ok());
    EXPECT_EQ(frame("h", f), whole->pixels.rgb) << "frame " << f;
  }
  EXPECT_EQ(renderer.prepares(), 3);
  EXPECT_EQ(renderer.geometry_reuses(), 2);
  // Another scene's frame takes the one place: the spheres' geometry goes,
  // and their next frame is prepared afresh.
  frame("t", 1);
  EXPECT_EQ(renderer.geometry_reuses(), 2);
  auto whole = render_image(frame_scene(*scene, 32, 24, 2, 1, 3, 60), params);
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(frame("h", 2), whole->pixels.rgb);
  EXPECT_EQ(renderer.prepares(), 5);
  EXPECT_EQ(renderer.geometry_reuses(), 2);
  EXPECT_EQ(frame("h", 3).size(), 32u * 24 * 3);
  EXPECT_EQ(renderer.geometry_reuses(), 3);
}

}  // namespace
}  // namespace locus::farm
