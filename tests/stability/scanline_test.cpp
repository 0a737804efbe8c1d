// Stability: scenes built to break the scanline pass (visible faces per
// sample line, multi-scanning coverage). tests/stability/README.md lists
// each case, its expectation and its bounds; stability.h the checks every
// case goes through.
#include <gtest/gtest.h>

#include <cmath>

#include "tests/stability/stability.h"

namespace locus {
namespace stability {
namespace {

// A diffuse, a mirror and a glass sphere resting on the floor: each touches
// it at one point, where the floor meets the sphere's shadow and the sphere
// meets its own reflection; the glass sphere's shadow has a dark core
// (beyond the critical angle) that closes at the contact. Each bounding
// icosahedron reaches below the floor's plane. Expect: no background
// between sphere and floor, no light leaking under the contacts, every
// mode as the reference.
TEST(Stability, SphereTangentToFloor) {
  Scene s = camera_scene(Vec3(0.3, 0.35, 6), Vec3(0, 0.5, 0), 38, 64, 64);
  s.materials = {diffuse(Color(0.9, 0.85, 0.8)), diffuse(Color(0.9, 0.3, 0.2)), mirror(0.7), glass(1.5, 0.9)};
  s.lights = {Light{Vec3(2, 6, -2.5), std::nullopt}, Light{Vec3(-4, 3, 4), std::nullopt}};
  s.objects.push_back(floor_quad(30, 0));
  s.objects.push_back(sphere(Vec3(-1.3, 1, 0), 1.0, 1));
  s.objects.push_back(sphere(Vec3(1.3, 0.7, 0.3), 0.7, 2));
  s.objects.push_back(sphere(Vec3(0.2, 0.4, 1.8), 0.4, 3));
  check_case(s, Bounds{}, "sphere tangent to floor");
}

// Three prisms and a box cutting through each other and through the floor:
// the visible boundaries are lines of intersection, found per sample line
// where the faces' depth order changes.
TEST(Stability, InterpenetratingPrisms) {
  Scene s = camera_scene(Vec3(3, 3.5, 6), Vec3(0, 0.7, 0), 40, 64, 64);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)),
                 diffuse(Color(0.3, 0.4, 0.9)), mirror(0.6)};
  s.lights = {Light{Vec3(4, 7, 3), std::nullopt}};
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(object(make_prism(6, 0.8, Vec3(-2, 0.8, 0), Vec3(2, 0.8, 0.3)), 1));
  s.objects.push_back(object(make_prism(3, 1.0, Vec3(0.2, -0.5, -0.3), Vec3(-0.3, 2.5, 0.4), 17), 2));
  s.objects.push_back(object(make_prism(5, 0.6, Vec3(-1, 0.2, -1.5), Vec3(1.2, 1.6, 1.6), 40), 4));
  s.objects.push_back(box(Vec3(-0.5, -0.3, -0.5), Vec3(0.7, 0.5, 0.9), 3));
  check_case(s, Bounds{}, "interpenetrating prisms");
}

// Coplanar overlapping faces: two decals lying in the floor's plane and
// overlapping each other and the floor, two boxes whose front faces share a
// plane and overlap (the boxes interpenetrate), a box standing on the floor
// (bottom face in the floor's plane). Coincident surfaces resolve to the one
// defined first, in every mode (docs/renderer.md); no face shadows the face
// it lies in.
Scene coplanar_scene(const Color& loser) {
  Scene s = camera_scene(Vec3(1.5, 2.5, 5), Vec3(0, 0.3, 0), 45, 64, 64);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(loser),
                 diffuse(Color(0.3, 0.4, 0.9))};
  s.lights = {Light{Vec3(-3, 5, 4), std::nullopt}};
  // Decals first: they win the floor's plane where they lie.
  s.objects.push_back(quad(Vec3(-2, 0, 2), Vec3(0, 0, 2), Vec3(0, 0, 0.5), Vec3(-2, 0, 0.5), 1));
  s.objects.push_back(quad(Vec3(-1, 0, 1.5), Vec3(1, 0, 1.5), Vec3(1, 0, 0), Vec3(-1, 0, 0), 2));
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(box(Vec3(-0.5, 0, -1), Vec3(0.5, 1.2, 0.3), 3));
  s.objects.push_back(box(Vec3(0.2, 0, -0.8), Vec3(1.3, 0.8, 0.3), 1));
  // A quad doubled on the top face of the first box.
  s.objects.push_back(
      quad(Vec3(-0.4, 1.2, 0.2), Vec3(0.4, 1.2, 0.2), Vec3(0.4, 1.2, -0.6), Vec3(-0.4, 1.2, -0.6), 2));
  return s;
}

TEST(Stability, CoplanarOverlappingFaces) {
  const Scene s = coplanar_scene(Color(0.2, 0.8, 0.3));
  check_case(s, Bounds{}, "coplanar overlapping faces");
  // Where the second decal overlaps the first, and where the doubled quad
  // lies on the box's top, the surface defined later loses: giving it
  // another colour changes nothing there, in any mode.
  const std::vector<Vec2> at = {project(s, Vec3(-0.5, 0, 1.0)), project(s, Vec3(0, 1.2, -0.2))};
  EXPECT_EQ(max_change(s, coplanar_scene(Color(1, 0, 1)), at, "coplanar: the later surface recoloured"), 0.0);
  // And those pixels do show the first surfaces: the red decal, the blue box.
  const Image img = render_or_fail(s, params(Method::kRaytrace, Boxes::kNone, 0, 1), "coplanar");
  const float* red = img.pixel(static_cast<int>(at[0].x), static_cast<int>(at[0].y));
  const float* blue = img.pixel(static_cast<int>(at[1].x), static_cast<int>(at[1].y));
  EXPECT_GT(red[0], 2 * red[1]);
  EXPECT_GT(blue[2], 2 * blue[1]);
}

// Faces seen exactly edge-on: the eye lies in the plane of a free quad, of
// a box's top face and of another box's side face. They cover no area; the
// box faces next to them close the boxes with no background between.
// The eye at height 1 and x = 0: y = 1 projects onto sub-scanline y = 32
// of --aa 4 (and between the sample lines 31.5 and 32.5), x = 0 onto the
// pixel edge x = 32.
Scene edge_on_scene(const Color& quads) {
  Scene s = camera_scene(Vec3(0, 1, 6), Vec3(0, 1, 0), 40, 64, 64);
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)),
                 mirror(0.7, quads), diffuse(quads)};
  s.lights = {Light{Vec3(3, 5, 5), std::nullopt}};
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(box(Vec3(-2.2, 0, -1), Vec3(-0.8, 1, 0.5), 1));  // top face in the eye's plane
  s.objects.push_back(box(Vec3(0, 0, -1.5), Vec3(1.4, 1.8, 0), 2));    // side x = 0 through the eye
  s.objects.push_back(quad(Vec3(0.5, 1, 2), Vec3(2, 1, 2), Vec3(2, 1, 0.5), Vec3(0.5, 1, 0.5), 3));
  s.objects.push_back(quad(Vec3(0, 1.2, 2), Vec3(0, 2.2, 2), Vec3(0, 2.2, 0.5), Vec3(0, 1.2, 0.5), 4));
  return s;
}

TEST(Stability, FaceSeenEdgeOn) {
  const Scene s = edge_on_scene(Color(0.8));
  check_case(s, Bounds{}, "face seen edge-on");
  // The two free quads cover no area: recolouring them changes no pixel in
  // any mode (they still cast shadows, the same either way).
  EXPECT_EQ(max_change(s, edge_on_scene(Color(1, 0, 1)), {}, "edge-on quads recoloured"), 0.0);
}

// A surface of triangles whose vertices project exactly onto sample lines
// (y = j + 0.5), onto sub-scanlines of --aa 4 (y = j + k/4) and onto pixel
// centres, some edges running along those lines. The mesh is closed in the
// image: no sample between its triangles may see the background.
// Camera: the eye at the origin, 90 degrees, looking down -z; a point of
// image coordinates (x, y) at depth d is d ((2x/W - 1) t, (1 - 2y/H) t, -1)
// with t = tan 45 degrees as the renderer computes it.
Scene on_lines_scene(int w, int h, double xoff, double yoff) {
  Scene s = camera_scene(Vec3(0, 0, 0), Vec3(0, 0, -1), 90, w, h);
  s.materials = {diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)), diffuse(Color(0.3, 0.4, 0.9))};
  s.lights = {Light{Vec3(0.3, 0.5, 0.5), std::nullopt}};
  s.background = Color(1.0, 1.0, 0.0);
  const double t = std::tan(glm::radians(90.0) * 0.5);
  auto at = [&](double x, double y, double d) {
    return d * Vec3((2 * x / w - 1) * t, (1 - 2 * y / h) * t, -1.0);
  };
  Mesh m;
  const int n = 8;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      // Rows alternate sample lines and sub-scanlines; columns pixel centres
      // and pixel edges; interior vertices jitter by quarter pixels.
      const double jit = (i > 0 && i < n && j > 0 && j < n) ? 0.25 * ((i * 3 + j * 5) % 5 - 2) : 0;
      const double x = xoff + 7 * i + (i % 2 ? 0.5 : 0.0) + jit;
      const double y = yoff + 7 * j + (j % 2 ? 0.5 : 0.25 * (j % 4)) - jit;
      const double d = 2.0 + 0.4 * std::sin(1.3 * i + 0.7 * j);
      m.positions.push_back(at(x, y, d));
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      if ((i + j) % 2) {
        m.triangles.push_back({a, c, b});
        m.triangles.push_back({b, c, d});
      } else {
        m.triangles.push_back({a, c, d});
        m.triangles.push_back({a, d, b});
      }
    }
  }
  s.objects.push_back(object(m, 0));
  // A star of triangles around a pixel centre, every vertex on a sample line.
  const Vec2 c(w * 0.5 + 0.5, h * 0.5 + 0.5);
  for (int k = 0; k < 6; ++k) {
    const double a0 = k * M_PI / 3, a1 = (k + 1) * M_PI / 3;
    const Vec2 p(c.x + std::round(6 * std::cos(a0) * 4) / 4, c.y + std::round(6 * std::sin(a0)));
    const Vec2 q(c.x + std::round(6 * std::cos(a1) * 4) / 4, c.y + std::round(6 * std::sin(a1)));
    Object tri = object(Polygon{{at(c.x, c.y, 1.5), at(q.x, q.y, 1.5), at(p.x, p.y, 1.5)}}, 1 + k % 2);
    s.objects.push_back(tri);
  }
  return s;
}

TEST(Stability, VerticesOnScanlinesAndSubScanlines) {
  // Interior vertices at x = 4 + 7i (+0.5), y = 4 + 7j (+0.25 k): on
  // sample lines, sub-scanlines and pixel centres.
  const Scene s = on_lines_scene(64, 64, 4, 4);
  Bounds b;
  // Pixel centres lying on an edge (vertices at centres, edges along sample
  // lines): either side is right there, and no more pixels than those.
  auto ps = prepare_scene(s, params(Method::kLocal, Boxes::kNone, 0, 1));
  ASSERT_TRUE(ps.ok());
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) b.point_exceptions += distance_to_edge(*(*ps)->scan, x + 0.5, y + 0.5) < 1e-6;
  }
  std::printf("[vertices on scanlines] %d pixel centres on a projected edge\n", b.point_exceptions);
  EXPECT_GT(b.point_exceptions, 20);
  const CaseResult r = check_case(s, b, "vertices on scanlines");
  // The mesh covers [4, 60] x [4, 60]: no background inside it, any mode.
  for (const ModeResult& m : r.modes) {
    int leaks = 0;
    for (int y = 6; y < 58; ++y) {
      for (int x = 6; x < 58; ++x) leaks += bg_weight(m.img, m.img_bg, x, y) > 1e-6;
    }
    EXPECT_EQ(leaks, 0) << m.name << ": background inside the mesh";
  }
}

// An object crossing the hither sphere: a box from depth 0.4 to 3 and a
// sphere around depth 1 with hither = 1, over a floor that runs behind the
// eye. Eye rays start at hither, so they see the inside of the box and of
// the sphere where hither cuts them; the scanline pass projects those faces
// and lets eye rays decide there.
TEST(Stability, ObjectCrossingHither) {
  Scene s = camera_scene(Vec3(0, 1, 0), Vec3(0, 0.8, -3), 70, 64, 64);
  s.camera.hither = 1.0;
  s.materials = {diffuse(Color(0.8)), diffuse(Color(0.9, 0.3, 0.2)), diffuse(Color(0.2, 0.8, 0.3)),
                 glass(1.5, 0.8)};
  s.lights = {Light{Vec3(1, 3, 1), std::nullopt}};
  s.objects.push_back(floor_quad(20, 0));
  s.objects.push_back(box(Vec3(-1.2, 0.3, -3), Vec3(-0.1, 1.4, -0.4), 1));
  s.objects.push_back(sphere(Vec3(0.7, 1.1, -1.0), 0.6, 2));
  s.objects.push_back(sphere(Vec3(0.4, 0.5, -0.8), 0.35, 3));
  check_case(s, Bounds{}, "object crossing hither");
}

}  // namespace
}  // namespace stability
}  // namespace locus
