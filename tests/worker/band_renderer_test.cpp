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

}  // namespace
}  // namespace locus::farm
