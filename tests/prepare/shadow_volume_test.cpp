// Shadow volumes and configuration IV (paper §4.1; docs/shadow-volumes.md):
// containment against the ray tracer's shadow segments, the special cases
// of forming a volume, and whole images equal to the ray tracer's.
#include "common/prepare/shadow_volume.h"
#include "common/trace/shadow_search.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <random>

#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scan/scanline.h"
#include "common/scan/span_shadows.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene_io.h"
#include "common/trace/raytrace.h"
#include "tests/render_compare.h"
#include "tests/trace/shadow_scenes.h"

namespace locus {
namespace {

using testing_util::agreement_scenes;
using testing_util::camera_scene;
using testing_util::expect_bands_bit_identical;
using testing_util::expect_agreement;
using testing_util::quad;

// Does the open segment (p, light) cross a surface of primitive `prim`?
// The ray tracer's shadow test, for one occluder.
bool segment_crosses(const PrimitiveSet& set, int prim, const Vec3& p, const Vec3& light) {
  std::vector<Crossing> c;
  return intersect_all(set, prim, Ray{p, light - p}, 0.0, 1.0, c) > 0;
}

// Random points in a box, containment against the segment test: they must
// agree everywhere (random points are never within rounding of a boundary).
void expect_volumes_match_segments(const Scene& s, const Vec3& light, const Vec3& lo,
                                   const Vec3& hi, const char* what, uint32_t seed = 1) {
  const PrimitiveSet set = build_primitives(s);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(lo.x, hi.x), uy(lo.y, hi.y), uz(lo.z, hi.z);
  for (int prim = 0; prim < static_cast<int>(set.prims.size()); ++prim) {
    VolumeSet vs;
    int first = 0, count = 0;
    const PrimRef& ref = set.prims[prim];
    if (ref.kind == PrimKind::kConvex) {
      const ConvexPrim& c = set.convexes[ref.index];
      std::vector<HalfSpace> planes;
      for (size_t k = 0; k < c.normals.size(); ++k) planes.push_back({c.normals[k], c.offsets[k]});
      first = add_polyhedron_volume(vs, c.faces, planes, light, true);
      count = 1;
    } else if (ref.kind == PrimKind::kPolygon) {
      const PolygonPrim& p = set.polygons[ref.index];
      count = add_polygon_volumes(vs, p.verts, p.normal, p.offset, light);
      ASSERT_GE(count, 0) << what;
    } else {
      FAIL() << what << ": only polygons and polyhedra";
    }
    int shadowed = 0;
    for (int i = 0; i < 20000; ++i) {
      const Vec3 p(ux(rng), uy(rng), uz(rng));
      bool in = false;
      for (int v = first; v < first + count; ++v) in = in || vs.contains(v, p, 0.0);
      ASSERT_EQ(in, segment_crosses(set, prim, p, light))
          << what << ": prim " << prim << " point " << p.x << " " << p.y << " " << p.z;
      shadowed += in;
    }
    EXPECT_GT(shadowed, 0) << what << ": no point in the shadow, the test proves little";
  }
}

TEST(ShadowVolume, PointsJustInsideAndJustOutside) {
  // A unit square at z = 1 under a light at z = 3 above its centre: the
  // shadow at z = 0 is the square scaled by 3/2, edges at +-0.75.
  VolumeSet vs;
  const std::vector<Vec3> sq = {Vec3(-0.5, -0.5, 1), Vec3(0.5, -0.5, 1), Vec3(0.5, 0.5, 1),
                                Vec3(-0.5, 0.5, 1)};
  ASSERT_EQ(add_polygon_volumes(vs, sq, Vec3(0, 0, 1), 1.0, Vec3(0, 0, 3)), 1);
  for (double d : {1e-9, 1e-6, 1e-3}) {
    EXPECT_TRUE(vs.contains(0, Vec3(0.75 - d, 0, 0), 0.0)) << d;
    EXPECT_FALSE(vs.contains(0, Vec3(0.75 + d, 0, 0), 0.0)) << d;
    EXPECT_TRUE(vs.contains(0, Vec3(0, -0.75 + d, 0), 0.0)) << d;
    EXPECT_FALSE(vs.contains(0, Vec3(0, -0.75 - d, 0), 0.0)) << d;
    // The cap: just behind the square is in the shadow, just in front not.
    EXPECT_TRUE(vs.contains(0, Vec3(0.1, 0.1, 1 - d), 0.0)) << d;
    EXPECT_FALSE(vs.contains(0, Vec3(0.1, 0.1, 1 + d), 0.0)) << d;
  }
  // Slack widens the volume by that distance.
  EXPECT_TRUE(vs.contains(0, Vec3(0.1, 0.1, 1 + 1e-6), 2e-6));
}

TEST(ShadowVolume, PolyhedronAgreesWithShadowSegments) {
  Scene s;
  const auto hull = make_hull({Vec3(-1, -1, 0), Vec3(1.2, -0.8, 0.1), Vec3(0.9, 1.1, -0.2),
                               Vec3(-1.1, 0.8, 0.3), Vec3(0.1, 0.2, 1.5), Vec3(0.3, -0.1, -1.2)});
  ASSERT_TRUE(hull.has_value());
  Object o;
  o.shape = *hull;
  s.objects.push_back(o);
  s.materials.push_back(Material{});
  for (const Vec3& light : {Vec3(0.5, 4, 6), Vec3(-7, 0.3, 0.2), Vec3(0.2, 0.1, -5)}) {
    expect_volumes_match_segments(s, light, Vec3(-6), Vec3(6), "hull");
  }
}

TEST(ShadowVolume, LightExactlyOnAFacesPlane) {
  // The light in the plane x = 1 of the box's +x face (outside the box):
  // that face is seen edge-on; the volume is still exact.
  Scene s;
  s.materials.push_back(Material{});
  s.objects.push_back(box_object(Vec3(-1), Vec3(1)));
  expect_volumes_match_segments(s, Vec3(1, 0.5, 4), Vec3(-5), Vec3(5), "box, light on +x plane");
  expect_volumes_match_segments(s, Vec3(1, 1, 4), Vec3(-5), Vec3(5),
                                "box, light on an edge's line");
  // A polygon with the light in its plane casts nothing.
  VolumeSet vs;
  EXPECT_EQ(add_polygon_volumes(vs, {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0)}, Vec3(0, 0, 1),
                                0.0, Vec3(5, 5, 0)),
            0);
}

TEST(ShadowVolume, LightInsideAnObjectOrItsBox) {
  Scene s;
  s.materials.push_back(Material{});
  s.objects.push_back(box_object(Vec3(-1), Vec3(1)));
  // Inside a solid occluder: every point outside it is in its shadow (the
  // segment crosses its surface), no point inside.
  expect_volumes_match_segments(s, Vec3(0.2, -0.3, 0.5), Vec3(-4), Vec3(4), "light inside box");
  VolumeSet vs;
  const Polyhedron box = make_box(Vec3(-1), Vec3(1));
  std::vector<std::vector<Vec3>> faces;
  std::vector<HalfSpace> planes;
  for (const auto& f : box.faces) {
    std::vector<Vec3> pts;
    for (int v : f) pts.push_back(box.vertices[v]);
    const Vec3 n = glm::normalize(glm::cross(pts[1] - pts[0], pts[2] - pts[0]));
    planes.push_back({n, glm::dot(n, pts[0])});
    faces.push_back(pts);
  }
  // A box of the hierarchy (not solid) around the light bounds nothing:
  // every point is a candidate. On its surface, the same.
  for (const Vec3& light : {Vec3(0.2, -0.3, 0.5), Vec3(1, 0.3, 0.2), Vec3(1, 1, 1)}) {
    const int v = add_polyhedron_volume(vs, faces, planes, light, false);
    EXPECT_EQ(vs.volumes[v].kind, VolumeKind::kEverywhere);
    const int w = add_polyhedron_volume(vs, faces, planes, light, true);
    EXPECT_EQ(vs.volumes[w].kind, VolumeKind::kOutside);
  }
}

TEST(ShadowVolume, ConcavePolygonIsCutIntoConvexPieces) {
  // A star-like concave outline (an SPD gear's kind) casts exactly its
  // shadow; a self-intersecting pentagram cannot be cut and falls back to
  // exact tests.
  Scene s;
  s.materials.push_back(Material{});
  Polygon gear;
  for (int i = 0; i < 24; ++i) {
    const double a = 2 * M_PI * i / 24, r = i % 2 ? 1.0 : 0.55;
    gear.vertices.emplace_back(r * std::cos(a), r * std::sin(a), 0.3 * r * std::cos(a));
  }
  Object o;
  o.shape = gear;
  s.objects.push_back(o);
  expect_volumes_match_segments(s, Vec3(0.3, 0.2, 5), Vec3(-4, -4, -4), Vec3(4, 4, 0), "gear");
  const PrimitiveSet set = build_primitives(s);
  VolumeSet vs;
  const PolygonPrim& p = set.polygons[0];
  // 12 notches: triangles merged into a few convex pieces, not 22.
  const int pieces = add_polygon_volumes(vs, p.verts, p.normal, p.offset, Vec3(0.3, 0.2, 5));
  EXPECT_GT(pieces, 1);
  EXPECT_LE(pieces, 13);
  std::vector<Vec3> star;
  for (int i = 0; i < 5; ++i) {
    const double a = 2 * M_PI * (2 * i) / 5;
    star.emplace_back(std::cos(a), std::sin(a), 0);
  }
  EXPECT_EQ(add_polygon_volumes(vs, star, Vec3(0, 0, 1), 0.0, Vec3(0, 0, 5)), -1);
}

// Hand-made scenes of the special cases, each rendered in configuration IV
// and by the ray tracer: the same image (floor_scene: tests/trace/shadow_scenes.h).
void expect_iv_agrees(const Scene& s, const char* what) {
  const auto ex = expect_agreement(s, config_iv(), what);
  std::printf("%s: %d edge, %d shadow-boundary exceptions\n", what, ex.edge, ex.boundary);
}

TEST(ShadowVolumeScenes, OccluderCrossingTheLightsPlane) {
  // A tilted wall reaching above and below the light's height, and a sphere
  // beside it: part of each occluder lies on either side of any plane
  // through the light.
  Scene s = floor_scene(Vec3(1, 2.5, 1));
  s.objects.push_back(
      quad(Vec3(-1, 0.5, 0), Vec3(2.5, 0.5, -1), Vec3(2.5, 4, -0.5), Vec3(-1, 4, 0.5), 1));
  Object ball;
  ball.shape = Sphere{Vec3(-1.5, 2.5, 1.5), 0.8};
  s.objects.push_back(ball);
  expect_iv_agrees(s, "occluder crossing the light's plane");
}

TEST(ShadowVolumeScenes, LightInsideABoundingPolyhedronsCap) {
  // The light between a sphere and its bounding icosahedron: that volume
  // cannot be formed, every point gets the exact test against the sphere.
  Scene s = floor_scene(Vec3(0, 2.0 + 1.02, 0));
  Object ball;
  ball.shape = Sphere{Vec3(0, 2, 0), 1.0};
  s.objects.push_back(ball);
  s.objects.push_back(box_object(Vec3(1.5, 0, 1), Vec3(2.5, 1, 2), 1));
  const auto ps = prepare_scene(s, config_iv());
  ASSERT_TRUE(ps.ok());
  const LightVolumes& lv = (*ps)->volumes->lights[0];
  const auto& oc = lv.occluders[1];
  ASSERT_EQ(oc.count, 1);
  EXPECT_EQ(lv.set.volumes[oc.first].kind, VolumeKind::kEverywhere);
  expect_iv_agrees(s, "light inside a bounding polyhedron");
}

TEST(ShadowVolumeScenes, LightInsideAnObjectsBox) {
  // A long thin tilted prism whose world box holds the light.
  Scene s = floor_scene(Vec3(0.2, 2.2, 0.1));
  Object bar;
  bar.shape = make_prism(6, 0.15, Vec3(-2, 0.5, -1.5), Vec3(2, 3.5, 1.5));
  s.objects.push_back(bar);
  expect_iv_agrees(s, "light inside an object's box");
}

TEST(ShadowVolumeScenes, LightInsideAClosedRoom) {
  // Eye and light inside an opaque box: seen from inside, its walls are lit
  // (no crossing between them and the light); a cube on the floor shadows.
  Scene s = camera_scene(Vec3(0, 2, 3.5), Vec3(0, 1, 0), 70, 80, 60);
  s.lights = {Light{Vec3(1, 3.5, 1), std::nullopt}};
  s.objects.push_back(box_object(Vec3(-4, 0, -4), Vec3(4, 4, 4), 0));
  s.objects.push_back(box_object(Vec3(-1, 0, -1), Vec3(0.5, 1.2, 0.5), 1));
  expect_iv_agrees(s, "room");
}

TEST(ShadowVolumeScenes, CoincidentFaces) {
  // A doubled quad over the floor, and a quad lying on the floor.
  Scene s = floor_scene(Vec3(2, 6, 1));
  s.objects.push_back(
      quad(Vec3(-1, 1.5, 1), Vec3(1, 1.5, 1), Vec3(1, 1.5, -1), Vec3(-1, 1.5, -1), 1));
  s.objects.push_back(
      quad(Vec3(-1, 1.5, 1), Vec3(1, 1.5, 1), Vec3(1, 1.5, -1), Vec3(-1, 1.5, -1), 0));
  s.objects.push_back(quad(Vec3(2, 0, 3), Vec3(4, 0, 3), Vec3(4, 0, 1), Vec3(2, 0, 1), 1));
  expect_iv_agrees(s, "coincident faces");
}

TEST(ShadowVolumeScenes, BentPolygonCastsTheShadowTheRayTracerSees) {
  // A quad with one corner lifted off its plane: the ray tracer hits its
  // best-fit plane inside the outline dropped on two axes; the volume
  // follows the same outline.
  Scene s = floor_scene(Vec3(1, 5, 2));
  s.objects.push_back(quad(Vec3(-1.5, 1.5, 1), Vec3(1, 1.2, 1.2), Vec3(1.3, 2.2, -1.4),
                           Vec3(-1.2, 1.6, -1.1), 1));
  expect_iv_agrees(s, "bent quad");
}

TEST(ShadowVolumeScenes, LightBetweenTwoObjects) {
  // Two walls facing each other with the light between them: each shadows
  // what lies behind it, the light reaches the space between.
  Scene s = floor_scene(Vec3(0, 1.5, 0));
  s.objects.push_back(
      quad(Vec3(-2, 0.5, -1), Vec3(-2, 0.5, 1), Vec3(-2, 2.5, 1), Vec3(-2, 2.5, -1), 1));
  s.objects.push_back(
      quad(Vec3(2, 0.5, 1), Vec3(2, 0.5, -1), Vec3(2, 2.5, -1), Vec3(2, 2.5, 1), 1));
  s.objects.push_back(box_object(Vec3(-0.3, 2.5, -0.3), Vec3(0.3, 2.8, 0.3), 1));
  expect_iv_agrees(s, "light between two objects");
}

TEST(ShadowVolumeScenes, ConcaveAndSelfIntersectingOccluders) {
  Scene s = floor_scene(Vec3(0.5, 5, 0.5));
  Polygon gear, star;
  for (int i = 0; i < 24; ++i) {
    const double a = 2 * M_PI * i / 24, r = i % 2 ? 1.0 : 0.55;
    gear.vertices.emplace_back(-1.5 + r * std::cos(a), 2, r * std::sin(a));
  }
  for (int i = 0; i < 5; ++i) {
    const double a = 2 * M_PI * (2 * i) / 5;
    star.vertices.emplace_back(1.5 + std::cos(a), 1.5, std::sin(a));
  }
  Object g, st;
  g.shape = gear;
  st.shape = star;
  st.material = 1;
  s.objects = {s.objects[0], g, st};
  expect_iv_agrees(s, "concave and self-intersecting polygons");
}

// A random scene of boxes, prisms, flat and bent polygons, meshes, spheres,
// cones, ellipsoids and CSG, in opaque, glass and mirror materials, over a
// floor, lit by 1 to 3 lights.
Scene random_scene(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1), h(0, 1);
  Scene s = floor_scene(Vec3(0, 5, 0));
  s.lights.clear();
  const int lights = 1 + seed % 3;
  for (int j = 0; j < lights; ++j) {
    s.lights.push_back(Light{Vec3(3 * u(rng), 0.3 + 5 * h(rng), 3 * u(rng)), std::nullopt});
  }
  Material glass;
  glass.kd = 0.2;
  glass.t = 0.7;
  glass.ior = 1.3 + 0.4 * h(rng);
  glass.absorption = Color(0.2, 0.5, 0.1);
  Material mirror;
  mirror.kd = 0.3;
  mirror.ks = 0.6;
  s.materials.push_back(glass);   // 2
  s.materials.push_back(mirror);  // 3
  for (int k = 0; k < 8; ++k) {
    const Vec3 c(3 * u(rng), 0.2 + 2.5 * h(rng), 3 * u(rng));
    const int material = static_cast<int>(4 * h(rng));
    Object o;
    o.material = material;
    switch (static_cast<int>(8 * h(rng))) {
      case 0:
        o.shape = make_box(c - Vec3(0.1 + h(rng)), c + Vec3(0.1 + h(rng)));
        break;
      case 1:
        o.shape = make_prism(3 + static_cast<int>(5 * h(rng)), 0.2 + 0.5 * h(rng), c,
                             c + Vec3(u(rng), u(rng), u(rng)));
        break;
      case 2: {
        const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
        // Sometimes bent: the fourth corner off the plane of the others.
        const Vec3 bend = h(rng) < 0.3 ? 0.2 * Vec3(u(rng), u(rng), u(rng)) : Vec3(0);
        o.shape = Polygon{{c, c + a, c + a + b, c + b + bend}};
        break;
      }
      case 3: {
        Mesh m;
        m.positions = {c, c + Vec3(u(rng), u(rng), u(rng)), c + Vec3(u(rng), u(rng), u(rng)),
                       c + Vec3(u(rng), u(rng), u(rng))};
        m.triangles = {{0, 1, 2}, {0, 2, 3}, {0, 3, 1}};
        o.shape = m;
        break;
      }
      case 4:
        o.shape = Sphere{c, 0.2 + 0.6 * h(rng)};
        break;
      case 5:
        o.shape = Cone{c, 0.2 + 0.4 * h(rng), c + Vec3(u(rng), u(rng), u(rng)), 0.4 * h(rng),
                       h(rng) < 0.5};
        break;
      case 6: {
        // An ellipsoid: a unit sphere squashed and turned.
        o.shape = Sphere{Vec3(0), 1.0};
        o.world_from_object =
            glm::translate(Mat4(1.0), c) *
            glm::rotate(Mat4(1.0), 3 * u(rng), glm::normalize(Vec3(u(rng), 1, u(rng)))) *
            glm::scale(Mat4(1.0), Vec3(0.2 + 0.6 * h(rng), 0.2 + 0.3 * h(rng), 0.5));
        break;
      }
      default: {
        // A sphere minus a box, or a capped cylinder and a sphere joined;
        // the operands are objects too, rendered only through the node.
        Object a, b;
        a.shape = Sphere{c, 0.3 + 0.4 * h(rng)};
        a.material = material;
        const bool diff = h(rng) < 0.5;
        if (diff) {
          b.shape = make_box(c, c + Vec3(1));
        } else {
          b.shape = Cone{c, 0.2, c + Vec3(u(rng), 1, u(rng)), 0.2, true};
        }
        b.material = static_cast<int>(4 * h(rng));
        s.objects.push_back(a);
        s.objects.push_back(b);
        const int n = static_cast<int>(s.objects.size());
        o.shape = Csg{diff ? CsgOp::kDifference : CsgOp::kUnion, n - 2, n - 1};
        break;
      }
    }
    s.objects.push_back(o);
  }
  return s;
}

// Seeded random scenes: boxes, prisms, tilted quads, triangles, spheres,
// cylinders, ellipsoids, CSG and glass over a floor, with one to three
// lights placed anywhere, some inside objects' boxes. Each failure names
// its seed.
TEST(ShadowVolumeScenes, RandomScenesAgreeWithRayTracer) {
  int edge = 0, boundary = 0;
  for (uint32_t seed = 1; seed <= 40; ++seed) {
    const Scene s = random_scene(seed);
    const std::string what = "seed " + std::to_string(seed);
    const auto ex = expect_agreement(s, config_iv(), what);
    edge += ex.edge;
    boundary += ex.boundary;
    if (::testing::Test::HasFailure()) return;
  }
  std::printf("random scenes: %d edge, %d shadow-boundary exceptions\n", edge, boundary);
}

// Multi-scanning finds each span's candidate occluders once per group of
// sub-scanlines (SpanShadows::set_group_rows, with the group's image
// rectangle); every line must still get the intervals its own walk of the
// hierarchy gives, and exactly the same light states.
void expect_groups_equal_walks(const Scene& scene, const std::string& what, int* compared,
                               size_t* extra) {
  RenderParams p = config_iv();
  p.aa = 4;
  // The volumes' line groups are what is tested: `auto` would choose shadow
  // rays for the small frames of many of these scenes (shadows_by_rays).
  p.shadows = ShadowPass::kVolumes;
  auto ps = prepare_scene(scene, p);
  ASSERT_TRUE(ps.ok()) << what << ": " << ps.status().message();
  const PreparedScene& s = **ps;
  ASSERT_TRUE(s.volumes) << what;
  const CameraFrame& cam = s.camera;
  Stats stats;
  SpanShadows grouped(s, 0.0, stats), walked(s, 0.0, stats);
  grouped.set_group_rows(8.0);
  std::vector<double> xa, xb;
  for (int k = 0; k <= 4 * cam.height; ++k) {
    const double y = k / 4.0;
    grouped.set_line(y);
    walked.set_line(y);
    const int row = std::min(k / 4, cam.height - 1);
    for (const int f : s.scan->cover[row]) {
      const ScanFace& face = s.scan->faces[f];
      if (y < face.ymin || y > face.ymax) continue;  // no span of it on this line
      // Over the face's own extent: its spans lie there, and the group
      // keeps only the occluders that reach it.
      double x0 = cam.width, x1 = 0;
      for (const Vec2& q : face.outline) {
        x0 = std::min(x0, q.x);
        x1 = std::max(x1, q.x);
      }
      x0 = std::max(x0, 0.0);
      x1 = std::min(x1, static_cast<double>(cam.width));
      if (!(x0 < x1)) continue;
      grouped.begin_span(f, x0, x1);
      walked.begin_span(f, x0, x1);
      xa.clear();
      xb.clear();
      grouped.breakpoints(xa);
      walked.breakpoints(xb);
      // The group's candidates include the line's own, so its intervals
      // include the line's. It may add slivers of curved bodies' or
      // transparent occluders' volumes (the slack of a sharp corner reaches
      // past its box's): they only call for the exact test, whose answer
      // the states below compare.
      std::vector<double> sa = xa, sb = xb;
      std::sort(sa.begin(), sa.end());
      std::sort(sb.begin(), sb.end());
      ASSERT_TRUE(std::includes(sa.begin(), sa.end(), sb.begin(), sb.end()))
          << what << ": breakpoints of face " << f << " at y " << y;
      *extra += sa.size() - sb.size();
      // The states between breakpoints, and near the line's ends.
      std::vector<double> xs = {x0 + 0.25 * (x1 - x0), x0 + 0.75 * (x1 - x0)};
      std::vector<double> all = xa;
      all.insert(all.end(), xb.begin(), xb.end());
      std::sort(all.begin(), all.end());
      for (size_t i = 0; i + 1 < all.size(); ++i) {
        if (all[i + 1] - all[i] > 1e-6) xs.push_back(0.5 * (all[i] + all[i + 1]));
      }
      for (const double x : xs) {
        // Only where the face's plane lies in front of the eye.
        const Vec3 d = cam.direction(x, y);
        const double num = face.offset - glm::dot(face.normal, cam.from);
        if (num / glm::dot(face.normal, d) <= 0) continue;
        ASSERT_EQ(grouped.states(x), walked.states(x))
            << what << ": light states on face " << f << " at (" << x << ", " << y << ")";
        const double u0 = std::max(x0, x - 0.1), u1 = std::min(x1, x + 0.1);
        ASSERT_TRUE(grouped.uncertain(u0, u1) || !walked.uncertain(u0, u1))
            << what << ": face " << f << " at (" << x << ", " << y << ")";
        ++*compared;
      }
    }
  }
}

TEST(ShadowVolumeScenes, LineGroupsGiveEachLineItsOwnIntervals) {
  int compared = 0;
  size_t extra = 0;
  for (uint32_t seed = 1; seed <= 40; ++seed) {
    Scene s = random_scene(seed);
    s.camera.width = 48;
    s.camera.height = 36;
    expect_groups_equal_walks(s, "seed " + std::to_string(seed), &compared, &extra);
    if (::testing::Test::HasFailure()) return;
  }
  for (const char* name : {"gears", "rings", "balls"}) {
    auto scene = load_scene(std::string(LOCUS_SHARED_DIR) + "/spd/s1/" + name + ".nff");
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = 64;
    scene->camera.height = 64;
    expect_groups_equal_walks(*scene, name, &compared, &extra);
  }
  std::printf("line groups: %d samples compared, %zu extra breakpoints\n", compared, extra);
  EXPECT_GT(compared, 10000);
}

// Issue #5 item 8: IV's image equals the ray tracer's on every scene.
TEST(ShadowVolumeScenes, AgreesWithRayTracerOnEveryScene) {
  const auto scenes = agreement_scenes();
  ASSERT_GE(scenes.size(), 20u) << "the SPD scenes were not found";
  int edge = 0, boundary = 0;
  for (const std::string& path : scenes) {
    auto scene = load_scene(path);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = 96;
    scene->camera.height = 72;
    const auto ex = expect_agreement(*scene, config_iv(), path);
    edge += ex.edge;
    boundary += ex.boundary;
  }
  RecordProperty("edge_exceptions", edge);
  RecordProperty("shadow_boundary_exceptions", boundary);
  std::printf("IV vs raytrace: %zu scenes, %d pixels excepted at edges, %d on shadow boundaries\n",
              scenes.size(), edge, boundary);
}

TEST(ShadowVolumeScenes, BandsStitchBitIdentical) {
  for (const char* name : {"/scenes/paper/c_thermometer.json", "/scenes/paper/a_glass.json"}) {
    expect_bands_bit_identical(std::string(LOCUS_SOURCE_DIR) + name, config_iv());
  }
}

TEST(ShadowVolumeScenes, FewerShadowRaysThanConfigurationIII) {
  for (const char* name : {"d_spheres_1light", "d_spheres_3lights"}) {
    auto scene = load_scene(std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/" + name + ".json");
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = 128;
    scene->camera.height = 128;
    RenderParams p = config_iv();
    p.boxes = Boxes::kEye;
    auto iii = render_image(*scene, p);
    // The paper's IV: its points search the volumes (--shadows volumes;
    // auto casts rays from them, AutoCastsRaysFromPointsForTheSameImage).
    p.boxes = Boxes::kEyeShadow;
    p.shadows = ShadowPass::kVolumes;
    auto iv = render_image(*scene, p);
    ASSERT_TRUE(iii.ok() && iv.ok());
    EXPECT_EQ(iii->stats.shadow_method, "volumes+rays");
    EXPECT_EQ(iv->stats.shadow_method, "volumes");
    // Both find the spans' shadows with volumes; III meets every
    // occluder's volume, IV only those the boxes and candidate lists leave.
    EXPECT_GT(iv->stats.tests_shadow_volume, 0u);
    EXPECT_LT(iv->stats.tests_shadow_volume, iii->stats.tests_shadow_volume) << name;
    // Secondary points: III casts a shadow ray per point and light, IV
    // tests containment, and only curved occluders need an exact test.
    EXPECT_LT(iv->stats.rays_shadow, iii->stats.rays_shadow) << name;
    EXPECT_LT(iv->stats.tests_ray_object * 2, iii->stats.tests_ray_object) << name;
    std::printf("%s: III %llu shadow rays, %llu volume tests; IV %llu, %llu\n", name,
                (unsigned long long)iii->stats.rays_shadow,
                (unsigned long long)iii->stats.tests_shadow_volume,
                (unsigned long long)iv->stats.rays_shadow,
                (unsigned long long)iv->stats.tests_shadow_volume);
    EXPECT_EQ(iv->stats.rays_eye, iii->stats.rays_eye);
    const std::string json = iv->stats.to_json();
    EXPECT_NE(json.find("\"shadow_volume\": "), std::string::npos);
    EXPECT_NE(json.find("\"ray_object\": "), std::string::npos);
    EXPECT_NE(json.find("\"method\": \"volumes\""), std::string::npos);
  }
}

// --shadows auto where the spans' shadows are the volumes': the points
// reached by secondary rays cast shadow rays instead of searching the
// volumes' hierarchy (PreparedScene::point_shadows_by_rays), and the image
// is the paper's IV's, bit for bit. Paper scenes (a) and (d), and SPD balls
// and rings (mirrors, glass, curved occluders).
TEST(ShadowVolumeScenes, AutoCastsRaysFromPointsForTheSameImage) {
  const std::string spd = std::string(LOCUS_SHARED_DIR) + "/spd";
  for (const std::string& path :
       {std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/a_glass.json",
        std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/d_spheres_3lights.json",
        spd + "/s1/balls.nff", spd + "/s1/rings.nff"}) {
    auto scene = load_scene(path);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = 96;
    scene->camera.height = 72;
    RenderParams p = config_iv();
    p.aa = 4;
    p.shadows = ShadowPass::kVolumes;
    auto paper = prepare_scene(*scene, p);
    p.shadows = ShadowPass::kAuto;
    auto mixed = prepare_scene(*scene, p);
    ASSERT_TRUE(paper.ok() && mixed.ok());
    ASSERT_TRUE((*mixed)->volumes) << path << ": auto chose rays for the spans too";
    EXPECT_FALSE((*paper)->point_shadows_by_rays);
    EXPECT_TRUE((*mixed)->point_shadows_by_rays);
    const BandResult a = render_band(**paper, Band{0, 72}, p);
    const BandResult b = render_band(**mixed, Band{0, 72}, p);
    EXPECT_EQ(a.stats.shadow_method, "volumes") << path;
    EXPECT_EQ(b.stats.shadow_method, "volumes+rays") << path;
    // The same points, asked another way.
    EXPECT_GT(b.stats.rays_shadow, a.stats.rays_shadow) << path;
    EXPECT_LT(b.stats.tests_shadow_volume, a.stats.tests_shadow_volume) << path;
    EXPECT_EQ(b.stats.rays_eye, a.stats.rays_eye) << path;
    ASSERT_EQ(a.pixels.rgb.size(), b.pixels.rgb.size());
    size_t differ = 0;
    for (size_t i = 0; i < a.pixels.rgb.size(); ++i) differ += a.pixels.rgb[i] != b.pixels.rgb[i];
    EXPECT_EQ(differ, 0u) << path;
  }
}

TEST(ShadowVolumeScenes, OpaquePolygonalShadowsCastNoRay) {
  Scene s = floor_scene(Vec3(2, 6, 1));
  s.objects.push_back(box_object(Vec3(-1, 0, -1), Vec3(1, 1.5, 1), 1));
  s.objects.push_back(quad(Vec3(1, 2, 1), Vec3(3, 2, 1), Vec3(3, 2.5, -1), Vec3(1, 2.5, -1), 1));
  auto r = render_image(s, config_iv());
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->stats.rays_shadow, 0u);
  EXPECT_EQ(r->stats.rays_eye, 0u);
  EXPECT_GT(r->stats.tests_shadow_volume, 0u);
  expect_iv_agrees(s, "opaque polygonal shadows");
}

// A glass cylinder (n = 1.52, capped, absorbing) and a glass box above a
// floor, as paper scene (a): t_pj through them by eqs. (2) and (3).
Scene glass_scene() {
  Scene s = floor_scene(Vec3(0.5, 7, 1.5));
  Material glass;
  glass.color = Color(0.9);
  glass.kd = 0.1;
  glass.ks = 0.1;
  glass.t = 0.85;
  glass.ior = 1.52;
  glass.absorption = Color(0.05, 0.3, 0.6);
  s.materials.push_back(glass);
  Object cyl;
  cyl.shape = Cone{Vec3(-2.5, 1.2, -1), 0.8, Vec3(1.5, 1.2, -1), 0.8, true};
  cyl.material = 2;
  s.objects.push_back(cyl);
  s.objects.push_back(box_object(Vec3(0.5, 0.4, 1), Vec3(2, 1.4, 2.5), 2));
  return s;
}

// Every shadow-ray origin gets the very same t_pj from the volumes as from
// a shadow ray: the same crossings, multiplied in the same order.
TEST(ShadowVolumeScenes, GlassShadowsEqualRayTracedTransmittance) {
  const Scene s = glass_scene();
  RenderParams rt;
  auto ref = prepare_scene(s, rt);
  auto iv = prepare_scene(s, config_iv());
  ASSERT_TRUE(ref.ok() && iv.ok());
  Stats rs, vs;
  Tracer tracer(**ref, rs);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(-6, 6), uz(-6, 6);
  int tinted = 0, dark = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p(ux(rng), 0, uz(rng));
    // Floor point: primitive 0, normal +y.
    const Color want = tracer.transmittance(p, Vec3(0, 1, 0), 0);
    const Vec3 origin = p + (*iv)->eps * Vec3(0, 1, 0);
    for (int receiver : {0, -1}) {
      const Color got = volume_transmittance(**iv, origin, 0, receiver, vs);
      ASSERT_EQ(got, want) << "point " << p.x << " " << p.z << " receiver " << receiver;
    }
    tinted += want != Color(1.0) && want != Color(0.0);
    dark += want == Color(0.0);
  }
  EXPECT_GT(tinted, 100);
  EXPECT_GT(dark, 10) << "no point beyond the critical angle (paper Fig. 8a)";
  EXPECT_LT(vs.rays_shadow, rs.rays_shadow);
  expect_iv_agrees(s, "glass shadows");
}

// Paper Fig. 8(a): where the straight path through the glass cylinder
// leaves it beyond the critical angle, no light of that source reaches the
// floor; the rest of the cylinder's shadow is tinted, not black.
TEST(ShadowVolumeScenes, DarkCoreBeyondTheCriticalAngle) {
  Scene s = glass_scene();
  s.objects.pop_back();  // the cylinder only
  s.ambient = 0.0;
  auto r = render_image(s, config_iv());
  ASSERT_TRUE(r.ok());
  auto ps = prepare_scene(s, config_iv());
  ASSERT_TRUE(ps.ok());
  // Walk the floor across the cylinder's shadow under the light: x = 0.5.
  Stats stats;
  int dark = 0, tinted = 0;
  const Vec3 light = s.lights[0].position;
  for (int i = 0; i <= 400; ++i) {
    const double z = -4 + 6.0 * i / 400;
    const Vec3 p(0.5, 0, z);
    const Color t = volume_transmittance(**ps, p + (*ps)->eps * Vec3(0, 1, 0), 0, 0, stats);
    // The straight segment's angle at the cylinder: its distance from the
    // axis (y = 1.2, z = -1) over the radius is sin of the incidence angle.
    const Vec3 d = glm::normalize(light - p);
    const Vec3 axis(1, 0, 0);
    const Vec3 rel = p - Vec3(0, 1.2, -1);
    const Vec3 dperp = d - glm::dot(d, axis) * axis;
    const Vec3 rperp = rel - glm::dot(rel, axis) * axis;
    const double dist = glm::length(glm::cross(rperp, glm::normalize(dperp)));
    const double sin_i = dist / 0.8;
    if (sin_i > 1.0) continue;  // misses the cylinder
    // Inside the glass the straight path meets the exit at the same angle,
    // beyond the critical angle when sin_i > 1 / 1.52.
    if (sin_i > 1.0 / 1.52 + 1e-6) {
      EXPECT_EQ(t, Color(0.0)) << "z " << z;
      ++dark;
    } else if (sin_i < 1.0 / 1.52 - 1e-6) {
      EXPECT_GT(t.x, 0.0) << "z " << z;
      ++tinted;
    }
  }
  EXPECT_GT(dark, 5);
  EXPECT_GT(tinted, 5);
  // And in the image: a floor pixel in the dark core has no light at all.
  const CameraFrame& cam = (*ps)->camera;
  bool found = false;
  for (int y = 0; y < cam.height && !found; ++y) {
    for (int x = 0; x < cam.width && !found; ++x) {
      const Ray ray{cam.from, cam.direction(x + 0.5, y + 0.5)};
      if (ray.dir.y >= 0) continue;
      const Vec3 p = cam.from + (-cam.from.y / ray.dir.y) * ray.dir;
      if (std::abs(p.x) > 3 || std::abs(p.z) > 7) continue;
      const Color t = volume_transmittance(**ps, p + (*ps)->eps * Vec3(0, 1, 0), 0, 0, stats);
      if (t != Color(0.0)) continue;
      // Not behind the cylinder from the eye: the floor is what is seen.
      std::vector<Crossing> c;
      if (intersect_all((*ps)->prims, 1, ray, 0, 1e9, c) > 0) continue;
      const float* px = r->pixels.pixel(x, y);
      EXPECT_EQ(px[0], 0.0f);
      EXPECT_EQ(px[1], 0.0f);
      EXPECT_EQ(px[2], 0.0f);
      found = true;
    }
  }
  EXPECT_TRUE(found) << "no pixel of the dark core is visible";
}

}  // namespace
}  // namespace locus
