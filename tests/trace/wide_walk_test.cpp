// The 8-wide ray walk (AVX2, Bvh::wide8) against the 4-wide one: the same
// images, bit for bit, and the same rays, on SPD scenes of every kind of
// primitive (polygons, triangles, spheres, cones, mixed), by the ray
// tracer and by configuration IV, whose spans are traced and whose shadows
// are searched through the same walk. On a processor without AVX2 no
// 8-wide tree is built, and that is what is checked.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "common/geometry/bvh.h"
#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

TEST(WideWalk, EightWideWalkRendersTheFourWideWalksImages) {
  const RenderParams traced = testing_util::raytrace_params(1);
  const RenderParams rays = testing_util::shadow_rays_params(2);
  const RenderParams local = testing_util::config_iv_params(2, 1);
  int compared = 0;
  for (const char* path :
       {"/spd/def/teapot.nff", "/spd/s1/gears.nff", "/spd/s1/balls.nff", "/spd/def/tetra.nff",
        "/spd/s2/rings.nff", "/spd/s1/sombrero.nff", "/spd/s2/mount.nff"}) {
    auto scene = load_scene(std::string(LOCUS_SHARED_DIR) + path);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = scene->camera.height = 64;
    for (const RenderParams& p : {traced, rays, local}) {
      const auto eight = std::make_unique<PreparedScene>(*scene, p);
      if (!wide8_walk_available()) {
        EXPECT_TRUE(eight->bvh.wide8.empty()) << path;
        continue;
      }
      ASSERT_FALSE(eight->bvh.wide8.empty()) << path;
      // The same geometry walked by the 4-wide tree.
      auto geometry = std::make_shared<SceneGeometry>(*scene, p);
      geometry->bvh.wide8.clear();
      build_wide(geometry->bvh);
      const auto four = std::make_unique<PreparedScene>(std::move(geometry), scene->camera, p);
      ASSERT_TRUE(four->bvh.wide8.empty() && !four->bvh.wide.empty()) << path;
      const BandResult x = render_band(*eight, Band{0, 64}, p);
      const BandResult y = render_band(*four, Band{0, 64}, p);
      EXPECT_EQ(testing_util::max_difference(x.pixels, y.pixels), 0.0) << path;
      EXPECT_EQ(x.stats.rays_eye, y.stats.rays_eye) << path;
      EXPECT_EQ(x.stats.rays_reflected, y.stats.rays_reflected) << path;
      EXPECT_EQ(x.stats.rays_refracted, y.stats.rays_refracted) << path;
      EXPECT_EQ(x.stats.rays_shadow, y.stats.rays_shadow) << path;
      EXPECT_GT(x.stats.tests_ray_object, 0u) << path;
      ++compared;
    }
  }
  EXPECT_EQ(compared, wide8_walk_available() ? 21 : 0);
}

}  // namespace
}  // namespace locus
