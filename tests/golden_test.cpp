// Small golden renders of the example scenes, compared numerically (max and
// RMS error). They cover what the NFF reference cannot: CSG, capped
// cylinders and cones, polyhedra, absorbing glass, coloured lights.
// Regenerate after an intended change with
//   LOCUS_UPDATE_GOLDEN=1 build/bin/locus_tests --gtest_filter='Golden*'
// and say why in the commit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>

#include "common/base/image.h"
#include "common/render.h"
#include "common/scene/scene_io.h"

namespace locus {
namespace {

struct GoldenCase {
  const char* scene;  // relative to the source tree
  const char* golden;
};

class Golden : public ::testing::TestWithParam<GoldenCase> {};

TEST_P(Golden, MatchesStoredRender) {
  const GoldenCase& c = GetParam();
  auto scene = load_scene(std::string(LOCUS_SOURCE_DIR) + "/" + c.scene);
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  scene->camera.width = 64;
  scene->camera.height = 64;
  RenderParams params;
  params.spp = 2;
  auto result = render_image(*scene, params);
  ASSERT_TRUE(result.ok()) << result.status().message();
  const std::string path = std::string(LOCUS_SOURCE_DIR) + "/tests/golden/" + c.golden;
  if (std::getenv("LOCUS_UPDATE_GOLDEN")) {
    ASSERT_TRUE(write_image(path, result->pixels).ok());
    GTEST_SKIP() << "golden written: " << path;
  }
  auto golden = read_image(path);
  ASSERT_TRUE(golden.ok()) << golden.status().message();
  ASSERT_EQ(golden->width, 64);
  ASSERT_EQ(golden->height, 64);
  double max_err = 0, sum_sq = 0;
  for (size_t i = 0; i < golden->rgb.size(); ++i) {
    const double e = std::fabs(static_cast<double>(golden->rgb[i]) - result->pixels.rgb[i]);
    max_err = std::max(max_err, e);
    sum_sq += e * e;
  }
  const double rms = std::sqrt(sum_sq / golden->rgb.size());
  // EXR stores the floats exactly; the slack covers compilers' rounding.
  EXPECT_LE(max_err, 1e-4) << c.scene;
  EXPECT_LE(rms, 1e-5) << c.scene;
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, Golden,
    ::testing::Values(GoldenCase{"scenes/paper/a_glass.json", "a_glass.exr"},
                      GoldenCase{"scenes/paper/b_desk.json", "b_desk.exr"},
                      GoldenCase{"scenes/paper/c_thermometer.json", "c_thermometer.exr"},
                      GoldenCase{"scenes/paper/d_spheres_2lights.json", "d_spheres_2lights.exr"},
                      GoldenCase{"scenes/simple/spheres.json", "spheres.exr"}),
    [](const ::testing::TestParamInfo<GoldenCase>& info) {
      std::string name = info.param.golden;
      return name.substr(0, name.find('.'));
    });

}  // namespace
}  // namespace locus
