// The ray walk's leaf-order copies of the simplest primitives
// (leaf_prims.h) answer exactly as the PrimitiveSet does: the same nearest
// crossing, bit for bit (t, normal, object, triangle and its u, v), and the
// same any-crossing answer, on random rays and cut segments.
#include "common/geometry/leaf_prims.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <glm/gtc/matrix_transform.hpp>
#include <random>
#include <set>

#include "common/geometry/bvh.h"
#include "common/geometry/geometry.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene.h"
#include "tests/random_unit.h"

namespace locus {
namespace {

uint64_t bits(double x) { return std::bit_cast<uint64_t>(x); }

void add(Scene& s, Shape shape, int material, const Mat4& xf = Mat4(1.0)) {
  Object o;
  o.shape = std::move(shape);
  o.material = material;
  o.world_from_object = xf;
  s.objects.push_back(std::move(o));
}

// Every kind the table copies, and ones it leaves to the PrimitiveSet (a
// scaled sphere and cone, a pentagon, a box), in and around the unit ball.
Scene mixed_scene() {
  Scene s;
  s.materials.push_back(Material{});  // opaque
  Material glass;
  glass.t = 0.8;
  glass.ior = 1.5;
  s.materials.push_back(glass);
  add(s, Sphere{Vec3(0.3, 0.2, -0.1), 0.4}, 0);
  add(s, Sphere{Vec3(-0.4, 0.1, 0.2), 0.3}, 1);
  add(s, Sphere{Vec3(0, 0, 0), 0.25}, 0,
      glm::scale(glm::translate(Mat4(1.0), Vec3(0.1, -0.5, 0)), Vec3(1, 0.5, 2)));
  add(s, Cone{Vec3(-0.2, -0.6, -0.3), 0.2, Vec3(0.1, 0.5, 0.2), 0.1, true}, 0);
  add(s, Cone{Vec3(0.4, -0.4, 0.4), 0.15, Vec3(0.4, 0.3, 0.4), 0.15, false}, 1);
  add(s, Cone{Vec3(0, 0, 0), 0.2, Vec3(0, 0, 0.5), 0.0, false}, 0,
      glm::rotate(Mat4(1.0), 0.7, Vec3(1, 0, 0)) * glm::scale(Mat4(1.0), Vec3(1, 2, 1)));
  add(s, Polygon{{Vec3(-0.9, -0.8, 0.1), Vec3(0.7, -0.6, -0.2), Vec3(0.1, 0.8, 0.3)}}, 0);
  add(s,
      Polygon{{Vec3(-0.5, -0.5, -0.6), Vec3(0.5, -0.5, -0.6), Vec3(0.6, 0.5, -0.5),
               Vec3(-0.5, 0.4, -0.7)}},
      1);
  add(s,
      Polygon{{Vec3(-0.3, 0.6, 0.6), Vec3(0.3, 0.6, 0.5), Vec3(0.5, 0.9, 0.55), Vec3(0.0, 1.0, 0.6),
               Vec3(-0.5, 0.9, 0.65)}},
      0);
  Mesh m;
  m.positions = {Vec3(-0.8, 0.3, -0.4), Vec3(0.2, 0.5, -0.9), Vec3(-0.1, -0.7, 0.8),
                 Vec3(0.9, 0.1, 0.2)};
  m.normals = {glm::normalize(Vec3(0, 0, 1)), glm::normalize(Vec3(0.2, 0, 1)),
               glm::normalize(Vec3(0, 0.3, 1)), glm::normalize(Vec3(-0.1, 0.1, 1))};
  m.triangles = {{0, 1, 2}, {1, 3, 2}};
  add(s, m, 0);
  add(s, make_box(Vec3(0.6, 0.6, -0.9), Vec3(0.9, 0.9, -0.6)), 0);
  return s;
}

TEST(LeafPrims, CopiesTheSimplestKindsInLeafOrder) {
  const Scene scene = mixed_scene();
  const PrimitiveSet set = build_primitives(scene);
  const Bvh bvh = build_bvh(set.bounds);
  std::vector<uint8_t> stops(set.prims.size());
  for (size_t i = 0; i < stops.size(); ++i) stops[i] = static_cast<uint8_t>(i % 2);
  const std::vector<LeafPrim> leaf = build_leaf_prims(set, bvh, stops);
  ASSERT_EQ(leaf.size(), bvh.order.size());
  std::set<LeafKind> kinds;
  for (size_t slot = 0; slot < leaf.size(); ++slot) {
    const int prim = bvh.order[slot];
    const PrimRef& ref = set.prims[prim];
    const LeafPrim& lp = leaf[slot];
    kinds.insert(lp.kind);
    LeafKind expected = LeafKind::kOther;
    if (ref.kind == PrimKind::kSphere && set.spheres[ref.index].frame.identity)
      expected = LeafKind::kSphere;
    if (ref.kind == PrimKind::kCone && set.cones[ref.index].frame.identity)
      expected = LeafKind::kCone;
    if (ref.kind == PrimKind::kTriangle) expected = LeafKind::kTriangle;
    if (ref.kind == PrimKind::kPolygon && set.polygons[ref.index].pts.size() <= 4)
      expected = LeafKind::kPolygon;
    EXPECT_EQ(lp.kind, expected) << "slot " << slot;
    EXPECT_EQ(lp.stops_light, stops[prim]) << "slot " << slot;
    EXPECT_EQ(lp.object, ref.object) << "slot " << slot;
  }
  // Every kind is there, copied or not (the scene's scaled quadrics, its
  // pentagon and its box stay with the PrimitiveSet).
  EXPECT_EQ(kinds.size(), 5u);
}

TEST(LeafPrims, AnswerAsThePrimitiveSetDoesBitForBit) {
  const Scene scene = mixed_scene();
  const PrimitiveSet set = build_primitives(scene);
  const Bvh bvh = build_bvh(set.bounds);
  const std::vector<LeafPrim> leaf =
      build_leaf_prims(set, bvh, std::vector<uint8_t>(set.prims.size(), 1));
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 o = 3.0 * random_unit(rng);
    const Ray ray{o, glm::normalize(Vec3(u(rng), u(rng), u(rng)) - o)};
    for (size_t slot = 0; slot < leaf.size(); ++slot) {
      if (leaf[slot].kind == LeafKind::kOther) continue;
      const int prim = bvh.order[slot];
      for (const auto& [tmin, tmax] : {std::pair{0.0, 1e9}, {2.5, 3.1}, {3.0, 1e9}, {0.0, 2.9}}) {
        const auto want = intersect_nearest(set, prim, ray, tmin, tmax);
        Crossing got;
        const bool hit = leaf_nearest(leaf[slot], ray, tmin, tmax, &got);
        ASSERT_EQ(hit, want.has_value()) << "ray " << i << " slot " << slot;
        const bool any = leaf_any(leaf[slot], ray, tmin, tmax);
        ASSERT_EQ(any, intersect_any(set, prim, ray, tmin, tmax))
            << "ray " << i << " slot " << slot;
        if (!hit) continue;
        ++hits;
        EXPECT_EQ(bits(got.t), bits(want->t));
        for (int a = 0; a < 3; ++a) EXPECT_EQ(bits(got.normal[a]), bits(want->normal[a]));
        EXPECT_EQ(got.leaf, want->leaf);
        EXPECT_EQ(got.tri, want->tri);
        EXPECT_EQ(bits(got.u), bits(want->u));
        EXPECT_EQ(bits(got.v), bits(want->v));
      }
    }
  }
  // Enough crossings for the comparison to mean something.
  EXPECT_GT(hits, 20000);
}

TEST(LeafPrims, NoTableWithoutAKindItCopies) {
  Scene s;
  s.materials.push_back(Material{});
  add(s, make_box(Vec3(0, 0, 0), Vec3(1, 1, 1)), 0);
  add(s, Sphere{Vec3(0, 0, 0), 1}, 0, glm::scale(Mat4(1.0), Vec3(2, 1, 1)));
  const PrimitiveSet set = build_primitives(s);
  const Bvh bvh = build_bvh(set.bounds);
  EXPECT_TRUE(build_leaf_prims(set, bvh, std::vector<uint8_t>(set.prims.size(), 1)).empty());
}

}  // namespace
}  // namespace locus
