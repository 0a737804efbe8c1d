// Stability: scenes built to break shadow volumes (configuration IV) and
// shadow rays. tests/stability/README.md lists each case, its expectation
// and its bounds.
#include <gtest/gtest.h>

#include "common/prepare/shadow_volume.h"
#include "tests/stability/stability.h"

namespace locus {
namespace stability {
namespace {

// A light exactly in the plane of a box's top face, of a free quad and of a
// prism's side face. Those faces get N.L = 0: no light at all, neither on
// them nor through rounding in a speckle; the shadows they cast are bounded
// by their silhouettes seen edge-on from the light (docs/shadow-volumes.md:
// such a face is not light-facing, the volume stays exact).
Scene light_on_plane_scene(bool first_light) {
  Scene s = camera_scene(Vec3(2.5, 4, 6), Vec3(0, 0.5, 0), 45, 64, 64);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)),
                 diffuse(Color(0.3, 0.4, 0.9))};
  // The first light lies in y = 1 (the box's top face and the quad) and in
  // the plane x = 1.5 of the second box's side face. Intensities are
  // explicit, so that the scene without it keeps the same light.
  s.ambient = 0.35;
  s.lights = {Light{Vec3(-3, 6, 2), Color(0.5)}};
  if (first_light) s.lights.insert(s.lights.begin(), Light{Vec3(1.5, 1, 3.5), Color(0.5)});
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(box(Vec3(-1.5, 0, -1), Vec3(0.2, 1, 0.5), 1));
  s.objects.push_back(box(Vec3(1.5, 0, -2), Vec3(2.5, 1.6, -0.8), 2));
  s.objects.push_back(quad(Vec3(-0.5, 1, 2.5), Vec3(0.6, 1, 2.5), Vec3(0.6, 1, 1.2), Vec3(-0.5, 1, 1.2), 3));
  return s;
}

TEST(Stability, LightExactlyOnAFacesPlane) {
  const Scene s = light_on_plane_scene(true);
  check_case(s, Bounds{}, "light on a face's plane");
  // N.L = 0 on the box's top face and on the quad: that light adds nothing
  // there. Removing it changes their pixels by rounding at most.
  const std::vector<Vec2> at = {project(s, Vec3(-0.65, 1, -0.25)), project(s, Vec3(0.05, 1, 1.85))};
  EXPECT_LE(max_change(s, light_on_plane_scene(false), at, "light in the faces' plane removed"), 1e-6);
  // Elsewhere (the floor, the boxes' sides) that light does count.
  const RenderParams p = params(Method::kRaytrace, Boxes::kNone, 0, 1);
  const Image with = render_or_fail(s, p, "with"), without = render_or_fail(light_on_plane_scene(false), p, "without");
  float most = 0;
  for (size_t k = 0; k < with.rgb.size(); ++k) most = std::max(most, with.rgb[k] - without.rgb[k]);
  EXPECT_GT(most, 0.1f);
}

// Lights inside bounding volumes: one inside the hierarchy's boxes (between
// the objects, inside the world box and a thin tilted prism's own box), one
// between a sphere and its bounding icosahedron. Those volumes cannot be
// formed: the box is a candidate everywhere, the sphere gets the exact test
// (docs/shadow-volumes.md). Expect the ray tracer's shadows.
TEST(Stability, LightInsideABoundingBox) {
  Scene s = camera_scene(Vec3(3, 5, 7), Vec3(0, 1, 0), 45, 64, 64);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)),
                 mirror(0.5)};
  s.lights = {Light{Vec3(0.2, 2.2, 0.1), std::nullopt}, Light{Vec3(-1.6, 1.2 + 0.7 * 1.03, -1.2), std::nullopt}};
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(object(make_prism(6, 0.15, Vec3(-2, 0.5, -1.5), Vec3(2, 3.5, 1.5)), 1));
  s.objects.push_back(box(Vec3(1, 0, -1), Vec3(1.8, 0.9, 0), 2));
  s.objects.push_back(box(Vec3(-1, 0, 0.8), Vec3(-0.3, 0.6, 1.6), 2));
  s.objects.push_back(sphere(Vec3(-1.6, 1.2, -1.2), 0.7, 3));
  s.objects.push_back(sphere(Vec3(0.9, 2.8, -0.5), 0.4, 1));
  // The scene does what it says: the first light lies in the prism's box
  // and in the hierarchy's root box, whose volumes are "everywhere"; the
  // second inside the sphere's bounding polyhedron but outside the sphere.
  auto ps = prepare_scene(s, params(Method::kLocal, Boxes::kEyeShadow, 0, 1));
  ASSERT_TRUE(ps.ok());
  const PreparedScene& p = **ps;
  const Aabb& prism_box = p.prims.bounds[1];
  EXPECT_TRUE(glm::all(glm::lessThan(prism_box.lo, s.lights[0].position)) &&
              glm::all(glm::lessThan(s.lights[0].position, prism_box.hi)));
  ASSERT_FALSE(p.volumes->lights[0].node_volume.empty());
  EXPECT_EQ(p.volumes->lights[0].set.volumes[p.volumes->lights[0].node_volume[0]].kind,
            VolumeKind::kEverywhere);
  const auto& ball = p.volumes->lights[1].occluders[4];
  ASSERT_EQ(p.prims.prims[4].object, 4);
  ASSERT_EQ(ball.count, 1);
  EXPECT_EQ(p.volumes->lights[1].set.volumes[ball.first].kind, VolumeKind::kEverywhere);
  check_case(s, Bounds{}, "light inside a bounding box");
}

}  // namespace
}  // namespace stability
}  // namespace locus
