// Bezier surfaces (issue #10): the scene format, analytic normals, the
// screen-space tolerance, crack-free stitching, the triangle count against
// distance, and agreement of the renderers on the tessellated teapot.
#include "common/prepare/tessellate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

const std::string kTeapot = LOCUS_SOURCE_DIR "/scenes/teapot.json";

Scene teapot(int w, int h) {
  auto s = load_scene(kTeapot);
  EXPECT_TRUE(s.ok()) << s.status().message();
  s->camera.width = w;
  s->camera.height = h;
  return *s;
}

int teapot_object(const Scene& s) {
  for (size_t i = 0; i < s.objects.size(); ++i) {
    if (std::holds_alternative<BezierSurface>(s.objects[i].shape)) return static_cast<int>(i);
  }
  return -1;
}

std::vector<BezierPatch> world_patches(const Scene& s, int object) {
  std::vector<BezierPatch> out = std::get<BezierSurface>(s.objects[object].shape).patches;
  for (BezierPatch& p : out) {
    for (Vec3& q : p.points) q = transform_point(s.objects[object].world_from_object, q);
  }
  return out;
}

size_t triangle_count(const Scene& s, double tol) {
  size_t n = 0;
  for (const Object& o : tessellate_scene(s, tol).objects) {
    if (const auto* m = std::get_if<Mesh>(&o.shape)) n += m->triangles.size();
  }
  return n;
}

std::string scene_text(const std::string& bezier) {
  return R"({"camera": {"from": [0, 0, 5], "at": [0, 0, 0], "width": 8, "height": 8},
             "materials": [{}], "objects": [{"bezier": )" +
         bezier + "}]}";
}

std::string numbers(int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += (i ? ", " : "") + std::to_string(i % 7);
  return out;
}

TEST(Bezier, TeapotLoadsAs32Patches) {
  const Scene s = teapot(32, 32);
  const int obj = teapot_object(s);
  ASSERT_GE(obj, 0);
  EXPECT_EQ(std::get<BezierSurface>(s.objects[obj].shape).patches.size(), 32u);
  EXPECT_TRUE(validate_scene(s).empty());
}

TEST(Bezier, JsonErrorsNameTheirPath) {
  auto ok = parse_scene_json(scene_text(R"({"patches": [{"points": [)" + numbers(48) + "]}]}"),
                             "s.json", "");
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  struct Case {
    std::string bezier, expected;
  };
  const Case cases[] = {
      {R"({"patches": [{"points": [)" + numbers(48) + "]}, {\"points\": [" + numbers(45) + "]}]}",
       "s.json: objects[0].bezier.patches[1].points: must hold 48 numbers (16 control points x, "
       "y, z in rows of four), got 45"},
      {R"({"patches": [{"points": [0, "NaN", )" + numbers(46) + "]}]}",
       "s.json: objects[0].bezier.patches[0].points[0]: must be finite, got [0, nan, 0]"},
      {R"({"patchs": []})", "s.json: objects[0].bezier.patchs: unknown field"},
      {R"({"patches": []})", "s.json: objects[0].bezier.patches: the surface has no patches"},
      {R"({"patches": [{"points": [1], "weights": [1]}]})",
       "s.json: objects[0].bezier.patches[0].weights: unknown field"},
  };
  for (const Case& c : cases) {
    auto r = parse_scene_json(scene_text(c.bezier), "s.json", "");
    ASSERT_FALSE(r.ok()) << c.bezier;
    EXPECT_NE(r.status().message().find(c.expected), std::string::npos)
        << r.status().message() << "\nexpected: " << c.expected;
  }
  // A bezier surface is not a solid: no CSG operand.
  auto csg = parse_scene_json(
      R"({"camera": {"from": [0, 0, 5], "at": [0, 0, 0], "width": 8, "height": 8},
          "materials": [{}], "objects": [
            {"bezier": {"patches": [{"points": [)" +
          numbers(48) + R"(]}]}},
            {"sphere": {"radius": 1}},
            {"csg": {"left": 0, "right": 1}}]})",
      "s.json", "");
  ASSERT_FALSE(csg.ok());
  EXPECT_NE(csg.status().message().find("objects[0] is a bezier, not a solid"), std::string::npos)
      << csg.status().message();
}

TEST(Bezier, TravelsToWorkersAsPatches) {
  const Scene s = teapot(32, 32);
  const v1::Scene proto = scene_to_proto(s);
  const int obj = teapot_object(s);
  ASSERT_TRUE(proto.objects(obj).has_bezier());
  EXPECT_EQ(proto.objects(obj).bezier().patches_size(), 32);
  auto back = scene_from_proto(proto, "wire");
  ASSERT_TRUE(back.ok()) << back.status().message();
  const auto& a = std::get<BezierSurface>(s.objects[obj].shape).patches;
  const auto& b = std::get<BezierSurface>(back->objects[obj].shape).patches;
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k].points, b[k].points);
  EXPECT_EQ(s.objects[obj].world_from_object, back->objects[obj].world_from_object);
  // A worker cuts the same triangles, bit for bit.
  const Mesh m1 = std::get<Mesh>(tessellate_scene(s, 0.25).objects[obj].shape);
  const Mesh m2 = std::get<Mesh>(tessellate_scene(*back, 0.25).objects[obj].shape);
  EXPECT_EQ(m1.positions, m2.positions);
  EXPECT_EQ(m1.normals, m2.normals);
  EXPECT_EQ(m1.triangles, m2.triangles);
}

TEST(Bezier, NormalsAreAnalyticAndFiniteAtCollapsedRows) {
  const Scene s = teapot(32, 32);
  const std::vector<BezierPatch> patches =
      std::get<BezierSurface>(s.objects[teapot_object(s)].shape).patches;
  const double ts[] = {0.0, 1e-12, 1e-3, 0.25, 0.5, 0.75, 1.0 - 1e-9, 1.0};
  for (size_t k = 0; k < patches.size(); ++k) {
    for (double u : ts) {
      for (double v : ts) {
        const Vec3 n = bezier_normal(patches[k], u, v);
        ASSERT_TRUE(is_finite(n)) << "patch " << k << " at " << u << ", " << v;
        EXPECT_NEAR(glm::length(n), 1.0, 1e-12) << "patch " << k;
      }
    }
  }
  // The data are z-up: the lid knob's top (patches 20-23, row v = 0
  // collapsed at (0, 0, 3.15)) and the bottom's centre (28-31, at the
  // origin) have the axis for their normal, from every side.
  for (int k = 20; k < 24; ++k) {
    for (double u : {0.0, 0.3, 1.0}) {
      EXPECT_NEAR(glm::dot(bezier_normal(patches[k], u, 0.0), Vec3(0, 0, 1)), 1.0, 1e-4) << k;
    }
  }
  for (int k = 28; k < 32; ++k) {
    for (double u : {0.0, 0.6, 1.0}) {
      EXPECT_NEAR(glm::dot(bezier_normal(patches[k], u, 0.0), Vec3(0, 0, -1)), 1.0, 1e-4) << k;
    }
  }
  // Away from collapsed rows the normal is the cross product of the
  // derivatives (central differences agree).
  const BezierPatch& body = patches[5];
  const double h = 1e-6, u = 0.3, v = 0.6;
  const Vec3 du = (bezier_point(body, u + h, v) - bezier_point(body, u - h, v)) / (2 * h);
  const Vec3 dv = (bezier_point(body, u, v + h) - bezier_point(body, u, v - h)) / (2 * h);
  EXPECT_NEAR(glm::dot(glm::normalize(glm::cross(du, dv)), bezier_normal(body, u, v)), 1.0, 1e-9);
  // Every vertex of the tessellation has one, at the vertex (not averaged).
  const SurfaceTessellation t =
      tessellate_surface(world_patches(s, teapot_object(s)), make_tess_view(s, 0.25));
  ASSERT_EQ(t.mesh.normals.size(), t.mesh.positions.size());
  for (const Vec3& n : t.mesh.normals) {
    ASSERT_TRUE(is_finite(n));
    EXPECT_NEAR(glm::length(n), 1.0, 1e-12);
  }
}

// Image position of a world point (SHADING.md camera, inverted).
Vec2 project(const TessView& view, const Camera& c, const Vec3& p) {
  const Vec3 d = p - view.eye;
  const double z = glm::dot(d, view.w);
  return Vec2(0.5 * c.width * (1.0 + glm::dot(d, view.u) / (z * view.tan_half * view.aspect)),
              0.5 * c.height * (1.0 - glm::dot(d, view.v) / (z * view.tan_half)));
}

bool in_frustum(const TessView& view, const Vec3& p) {
  const Vec3 d = p - view.eye;
  const double z = glm::dot(d, view.w);
  return z >= view.hither && std::abs(glm::dot(d, view.u)) <= view.tan_half * view.aspect * z &&
         std::abs(glm::dot(d, view.v)) <= view.tan_half * z;
}

// Largest screen distance between a point of a triangle and the surface
// point with the same parameters, over the triangles' points in the frustum.
double measured_deviation(const Scene& s, const SurfaceTessellation& t,
                          const std::vector<BezierPatch>& patches, const TessView& view) {
  double worst = 0;
  for (const auto& tri : t.mesh.triangles) {
    const int patch = t.vertex_patch[tri[0]];
    for (int a = 0; a <= 6; ++a) {
      for (int b = 0; a + b <= 6; ++b) {
        const double l1 = a / 6.0, l2 = b / 6.0, l0 = 1.0 - l1 - l2;
        const Vec3 q = l0 * t.mesh.positions[tri[0]] + l1 * t.mesh.positions[tri[1]] +
                       l2 * t.mesh.positions[tri[2]];
        if (!in_frustum(view, q)) continue;
        const Vec2 uv = l0 * t.uv[tri[0]] + l1 * t.uv[tri[1]] + l2 * t.uv[tri[2]];
        const Vec3 p = bezier_point(patches[patch], uv.x, uv.y);
        worst =
            std::max(worst, glm::length(project(view, s.camera, p) - project(view, s.camera, q)));
      }
    }
  }
  return worst;
}

TEST(Bezier, DeviationStaysBelowTheToleranceOnRandomViews) {
  const Scene base = teapot(128, 96);
  const int obj = teapot_object(base);
  const std::vector<BezierPatch> patches = world_patches(base, obj);
  for (uint32_t seed = 1; seed <= 6; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    Scene s = base;
    Vec3 dir;
    do dir = Vec3(uni(rng), uni(rng), uni(rng));
    while (glm::length(dir) > 1.0 || glm::length(dir) < 0.2);
    const double dist = 6.0 + 10.0 * (uni(rng) + 1.0);
    s.camera.at = Vec3(0.2, 1.4, 0) + 0.8 * Vec3(uni(rng), uni(rng), uni(rng));
    s.camera.from = s.camera.at + dist * glm::normalize(dir);
    s.camera.angle = 40.0 + 15.0 * uni(rng);
    for (double tol : {2.0, 0.5, 0.25}) {
      const TessView view = make_tess_view(s, tol);
      const SurfaceTessellation t = tessellate_surface(patches, view);
      const double worst = measured_deviation(s, t, patches, view);
      std::printf("view %u, --tess-tol %g: %zu triangles, largest deviation %.4f px\n", seed, tol,
                  t.mesh.triangles.size(), worst);
      EXPECT_LE(worst, tol) << "seed " << seed << ", --tess-tol " << tol;
      // Not needlessly fine either: the bound is within a few times the truth.
      EXPECT_GT(worst, tol / 20) << "seed " << seed << ", --tess-tol " << tol;
    }
  }
}

// Six patches closing a stretched, rounded cube around the origin: the
// control points are a 4 x 4 grid on each face of [-1, 1]^3, pushed onto the
// unit sphere and stretched 2.5x along x, so neighbouring patches differ in
// size and curvature (and so in rates) but share their boundary rows
// exactly. Every point within 0.5 of the origin is inside it.
BezierSurface closed_surface() {
  const double g[4] = {-1.0, -1.0 / 3.0, 1.0 / 3.0, 1.0};
  BezierSurface out;
  for (int axis = 0; axis < 3; ++axis) {
    for (double sign : {-1.0, 1.0}) {
      BezierPatch p;
      for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
          Vec3 c;
          c[axis] = sign;
          c[(axis + 1) % 3] = g[j];
          c[(axis + 2) % 3] = g[i];
          c = glm::normalize(c);
          c.x *= 2.5;
          p.points[4 * i + j] = c;
        }
      }
      out.patches.push_back(p);
    }
  }
  return out;
}

TEST(Bezier, NoBackgroundLeaksThroughAClosedSurfaceAtAnyTolerance) {
  Scene s = testing_util::camera_scene(Vec3(2.2, 1.6, 3.1), Vec3(0.2, 0, 0), 50, 96, 96);
  s.background = Color(1, 0, 1);
  s.materials[0].color = Color(0, 1, 0);  // red 0 everywhere on the surface
  Object o;
  o.shape = closed_surface();
  s.objects.push_back(o);
  ASSERT_TRUE(validate_scene(s).empty());
  const CameraFrame cam(s.camera);
  std::vector<RenderParams> methods(3);
  methods[0].method = Method::kRaytrace;
  methods[1].method = Method::kLocal;
  methods[2].method = Method::kLocal;
  methods[2].aa = 4;
  size_t rates_differ = 0;
  for (double tol : {8.0, 4.0, 1.0, 0.25, 0.05}) {
    const SurfaceTessellation t =
        tessellate_surface(closed_surface().patches, make_tess_view(s, tol));
    for (const auto& r : t.rates) rates_differ += r != t.rates[0];
    for (RenderParams p : methods) {
      p.tess_tol = tol;
      auto img = render_image(s, p);
      ASSERT_TRUE(img.ok());
      int inside = 0;
      for (int y = 0; y < s.camera.height; ++y) {
        for (int x = 0; x < s.camera.width; ++x) {
          const Vec3 d = cam.direction(x + 0.5, y + 0.5);
          const Vec3 to_origin = -cam.from;
          if (glm::length(to_origin - glm::dot(to_origin, d) * d) > 0.35) continue;
          ++inside;
          EXPECT_EQ(img->pixels.pixel(x, y)[0], 0.0f)
              << "pixel " << x << "," << y << " sees the background, --tess-tol " << tol
              << ", method " << (p.method == Method::kLocal ? "local" : "raytrace") << " aa "
              << p.aa;
        }
      }
      EXPECT_GT(inside, 150);
    }
  }
  EXPECT_GT(rates_differ, 0u);  // neighbours were cut to different depths
}

TEST(Bezier, TeapotHasNoCracksAtAnyTolerance) {
  // Against a very fine tessellation (ray traced, which sees the same
  // triangles as the scanline pass): a pixel may see the background only
  // where the reference sees it within tol + 1 pixels (silhouettes move by
  // up to the tolerance; the gap between the lid and the rim is real).
  const Scene s = teapot(96, 96);
  RenderParams p;
  p.tess_tol = 0.01;
  auto ref = render_image(s, p);
  ASSERT_TRUE(ref.ok());
  auto is_bg = [&](const Image& img, int x, int y) {
    const float* px = img.pixel(x, y);
    return px[0] == static_cast<float>(s.background.x) &&
           px[1] == static_cast<float>(s.background.y) &&
           px[2] == static_cast<float>(s.background.z);
  };
  for (double tol : {4.0, 1.0, 0.5, 0.25, 0.1, 0.05}) {
    for (Method m : {Method::kLocal, Method::kRaytrace}) {
      // The scanline pass is the slower to prepare: the three coarser ones.
      if (m == Method::kLocal && tol < 0.25) continue;
      RenderParams q;
      q.method = m;
      q.tess_tol = tol;
      auto img = render_image(s, q);
      ASSERT_TRUE(img.ok());
      const int r = static_cast<int>(std::ceil(tol)) + 1;
      for (int y = r; y + r < 96; ++y) {
        for (int x = r; x + r < 96; ++x) {
          if (!is_bg(img->pixels, x, y)) continue;
          bool near_bg = false;
          for (int dy = -r; dy <= r && !near_bg; ++dy) {
            for (int dx = -r; dx <= r && !near_bg; ++dx)
              near_bg = is_bg(ref->pixels, x + dx, y + dy);
          }
          EXPECT_TRUE(near_bg) << "crack at " << x << "," << y << ", --tess-tol " << tol;
        }
      }
    }
  }
}

TEST(Bezier, TriangleCountFallsWithDistance) {
  // Seen 4x farther away, at least 4x fewer triangles (issue #10). With a
  // tolerance on the deviation the count goes as 1/distance (the rate per
  // side as 1/sqrt(distance)), docs/tessellation.md.
  Scene s = teapot(256, 256);
  const Vec3 at = s.camera.at, dir = glm::normalize(s.camera.from - s.camera.at);
  std::vector<size_t> counts;
  for (double d : {8.0, 16.0, 32.0}) {
    s.camera.from = at + d * dir;
    counts.push_back(triangle_count(s, kDefaultTessTol));
  }
  std::printf("triangles at distance 8, 16, 32: %zu, %zu, %zu\n", counts[0], counts[1], counts[2]);
  EXPECT_GE(counts[0], 4 * counts[2]) << counts[0] << " vs " << counts[2];
  EXPECT_GE(10 * counts[0], 19 * counts[1]) << counts[0] << " vs " << counts[1];  // ~1/distance
  // And the tolerance: 4x the tolerance, about 4x fewer.
  s.camera.from = at + 8.0 * dir;
  EXPECT_GE(triangle_count(s, 0.25), 3 * triangle_count(s, 1.0));
}

TEST(Bezier, ASurfaceHasATriangleBudget) {
  const Scene s = teapot(256, 256);
  TessView view = make_tess_view(s, 0.25);
  const std::vector<BezierPatch> patches = world_patches(s, teapot_object(s));
  const size_t full = tessellate_surface(patches, view).mesh.triangles.size();
  view.max_triangles = 4000;
  const size_t capped = tessellate_surface(patches, view).mesh.triangles.size();
  EXPECT_GT(full, 20000u);
  EXPECT_LE(capped, 5000u);  // the budget counts 2 nu nv a patch; stitching adds a few
  EXPECT_GT(capped, 2000u);
}

TEST(Bezier, MirrorsRefineWhatTheEyeDoesNotSee) {
  // One patch behind the camera: coarse, unless a mirror could show it.
  Scene s = teapot(64, 64);
  const int obj = teapot_object(s);
  std::swap(s.camera.from, s.camera.at);
  const std::vector<BezierPatch> patches = world_patches(s, obj);
  const TessView plain = make_tess_view(s, 0.25);
  ASSERT_FALSE(plain.mirrors);
  const PatchScale coarse = patch_scale(plain, patches[5]);
  EXPECT_FALSE(coarse.in_view);
  s.materials[0].ks = 0.5;  // the floor becomes a mirror
  const TessView mirrored = make_tess_view(s, 0.25);
  ASSERT_TRUE(mirrored.mirrors);
  const PatchScale fine = patch_scale(mirrored, patches[5]);
  EXPECT_GE(fine.pixels_per_unit, 10 * coarse.pixels_per_unit);
  const auto r0 = patch_rates(patches[5], coarse.pixels_per_unit, 0.25);
  const auto r1 = patch_rates(patches[5], fine.pixels_per_unit, 0.25);
  EXPECT_GT(r1[0] * r1[1], 4 * r0[0] * r0[1]);
}

TEST(Bezier, ConfigurationsAgreeOnTheTeapot) {
  Scene s = teapot(64, 64);
  for (Boxes b : {Boxes::kNone, Boxes::kEye, Boxes::kEyeShadow}) {
    RenderParams local;
    local.method = Method::kLocal;
    local.boxes = b;
    local.tess_tol = 1.0;
    const auto ex = testing_util::expect_agreement(s, local, "teapot");
    EXPECT_LE(ex.edge + ex.boundary, 4);
  }
  // The ray tracer with and without boxes: bit-identical.
  RenderParams none, boxes;
  none.boxes = Boxes::kNone;
  auto a = render_image(s, none);
  auto b = render_image(s, boxes);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->pixels.rgb, b->pixels.rgb);
}

TEST(Bezier, BandsStitchBitIdentical) {
  RenderParams p;
  p.method = Method::kLocal;
  p.aa = 4;
  testing_util::expect_bands_bit_identical(kTeapot, p);
  testing_util::expect_bands_bit_identical(kTeapot, RenderParams{});
}

TEST(Bezier, TolerancesAreCheckedAndStatsCountTriangles) {
  const Scene s = teapot(32, 32);
  for (double bad : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    RenderParams p;
    p.tess_tol = bad;
    auto r = prepare_scene(s, p);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("--tess-tol must be a positive number of pixels"),
              std::string::npos)
        << r.status().message();
  }
  RenderParams p;
  p.method = Method::kLocal;
  auto r = render_image(s, p);
  ASSERT_TRUE(r.ok());
  EXPECT_GT(r->stats.geometry_triangles, 32u * 8);
  EXPECT_GE(r->stats.seconds_tessellate, 0.0);
  EXPECT_LE(r->stats.seconds_tessellate, r->stats.seconds_prepare);
  const std::string json = r->stats.to_json();
  EXPECT_NE(
      json.find("\"geometry\": {\"triangles\": " + std::to_string(r->stats.geometry_triangles)),
      std::string::npos)
      << json;
  EXPECT_NE(json.find("\"tessellate\": "), std::string::npos) << json;
}

}  // namespace
}  // namespace locus
