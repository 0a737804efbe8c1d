// Multi-scanning anti-aliasing (paper §3.3; METHOD.md §6; issue #6;
// docs/multiscan.md): exact coverage of straight edges, curved silhouettes
// by bisection, convergence to the supersampled ray tracer, and bands that
// stay bit-identical.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <random>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scan/multiscan.h"
#include "common/scan/scanline.h"
#include "common/scene/scene_io.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

using testing_util::camera_scene;
using testing_util::expect_bands_bit_identical;
using testing_util::quad;

RenderParams local_aa(int n, Boxes boxes = Boxes::kEyeShadow) {
  RenderParams p;
  p.method = Method::kLocal;
  p.boxes = boxes;
  p.aa = n;
  return p;
}

// A scene whose every surface has intensity exactly 1 (ambient only, white,
// no light) on a black background: a pixel's value is the area covered.
Scene coverage_scene(int w, int h) {
  Scene s = camera_scene(Vec3(0, 0, 10), Vec3(0, 0, 0), 40.0, w, h);
  s.lights.clear();
  s.ambient = 1.0;
  s.background = Color(0.0);
  s.materials.assign(1, Material{});
  s.materials[0].color = Color(1.0);
  s.materials[0].kd = 1.0;
  return s;
}

// Area of polygon `poly` (image coordinates) inside pixel (i, j).
double area_in_pixel(std::vector<Vec2> poly, int i, int j) {
  auto clip = [&](auto inside, auto cross) {
    std::vector<Vec2> out;
    for (size_t k = 0; k < poly.size(); ++k) {
      const Vec2 a = poly[k], b = poly[(k + 1) % poly.size()];
      if (inside(a)) out.push_back(a);
      if (inside(a) != inside(b)) out.push_back(cross(a, b));
    }
    poly = out;
  };
  auto at_x = [](double x) {
    return [x](Vec2 a, Vec2 b) { return a + (x - a.x) / (b.x - a.x) * (b - a); };
  };
  auto at_y = [](double y) {
    return [y](Vec2 a, Vec2 b) { return a + (y - a.y) / (b.y - a.y) * (b - a); };
  };
  clip([&](Vec2 p) { return p.x >= i; }, at_x(i));
  clip([&](Vec2 p) { return p.x <= i + 1; }, at_x(i + 1));
  clip([&](Vec2 p) { return p.y >= j; }, at_y(j));
  clip([&](Vec2 p) { return p.y <= j + 1; }, at_y(j + 1));
  double a = 0;
  for (size_t k = 0; k < poly.size(); ++k) {
    const Vec2 p = poly[k], q = poly[(k + 1) % poly.size()];
    a += p.x * q.y - q.x * p.y;
  }
  return std::abs(0.5 * a);
}

// Polygons: the trapezoidal rule is exact where one straight edge crosses a
// pixel from its top to its bottom; elsewhere (a vertex inside, an edge
// leaving through a side) the error falls as the sub-scanlines multiply.
TEST(Multiscan, CoverageOfPolygonEdgesIsExact) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  double prev_rms = 1e9;
  for (int n : {1, 4, 16}) {
    double sum2 = 0;
    int edge_pixels = 0, exact_pixels = 0;
    double worst_exact = 0, worst = 0;
    for (int trial = 0; trial < 4; ++trial) {
      Scene s = coverage_scene(40, 32);
      std::mt19937 shape_rng(100 + trial);
      std::uniform_real_distribution<double> v(-2.5, 2.5);
      s.objects.push_back(quad(Vec3(v(shape_rng), v(shape_rng), 0), Vec3(2.9, v(shape_rng), 0),
                               Vec3(v(shape_rng), 2.8, 0), Vec3(-2.7, v(shape_rng), 0), 0));
      auto ps = prepare_scene(s, local_aa(n));
      ASSERT_TRUE(ps.ok());
      ASSERT_EQ((*ps)->scan->faces.size(), 1u);
      const std::vector<Vec2>& outline = (*ps)->scan->faces[0].outline;
      const BandResult r = render_band(**ps, Band{0, 32}, local_aa(n));
      for (int j = 0; j < 32; ++j) {
        for (int i = 0; i < 40; ++i) {
          const double want = area_in_pixel(outline, i, j);
          const double got = r.pixels.pixel(i, j)[0];
          if (want <= 0 || want >= 1) {
            EXPECT_NEAR(got, want, 1e-6) << "pixel " << i << "," << j << " n " << n;
            continue;
          }
          ++edge_pixels;
          const double err = std::abs(got - want);
          sum2 += err * err;
          worst = std::max(worst, err);
          // One edge from the pixel's top to its bottom, no vertex inside.
          bool simple = true;
          int crossings = 0;
          for (size_t k = 0; k < outline.size(); ++k) {
            const Vec2 a = outline[k], b = outline[(k + 1) % outline.size()];
            if (a.x >= i && a.x <= i + 1 && a.y >= j && a.y <= j + 1) simple = false;
            const double lo = std::min(a.y, b.y), hi = std::max(a.y, b.y);
            if (lo < j + 1 && hi > j) {
              const double xt = a.x + (j - a.y) * (b.x - a.x) / (b.y - a.y);
              const double xb = a.x + (j + 1 - a.y) * (b.x - a.x) / (b.y - a.y);
              if (std::max(xt, xb) > i && std::min(xt, xb) < i + 1) {
                ++crossings;
                if (!(xt >= i && xt <= i + 1 && xb >= i && xb <= i + 1)) simple = false;
              }
            }
          }
          if (simple && crossings == 1) {
            ++exact_pixels;
            worst_exact = std::max(worst_exact, err);
          }
        }
      }
    }
    const double rms = std::sqrt(sum2 / edge_pixels);
    std::printf("aa %2d: %d edge pixels, rms %.2e, max %.2e; %d simple, max %.2e\n", n,
                edge_pixels, rms, worst, exact_pixels, worst_exact);
    EXPECT_GT(exact_pixels, 30);
    EXPECT_LT(worst_exact, 1e-5) << "aa " << n;  // floats: 2^-24 relative
    EXPECT_LT(worst, 0.5 / n + 1e-5) << "aa " << n;
    EXPECT_LT(rms, prev_rms);
    prev_rms = rms;
  }
}

// Two faces that interpenetrate: the visible boundary is their line of
// intersection, found exactly on every sub-scanline (paper §3.1), so the
// pixels along it get the exact mix.
TEST(Multiscan, InterpenetratingFacesSplitExactly) {
  Scene s = coverage_scene(48, 40);
  s.materials.push_back(s.materials[0]);
  s.materials[1].color = Color(0.0, 1.0, 0.0);
  s.materials[0].color = Color(1.0, 0.0, 0.0);
  // Two planes crossing along the line x = 0.3 y + 0.2 of the z = 0 plane.
  auto plane_z = [](double slope, double x, double y) { return slope * (x - 0.3 * y - 0.2); };
  const double e = 6.0;
  s.objects.push_back(quad(Vec3(-e, -e, plane_z(0.5, -e, -e)), Vec3(e, -e, plane_z(0.5, e, -e)),
                           Vec3(e, e, plane_z(0.5, e, e)), Vec3(-e, e, plane_z(0.5, -e, e)), 0));
  s.objects.push_back(quad(Vec3(-e, -e, plane_z(-0.5, -e, -e)), Vec3(e, -e, plane_z(-0.5, e, -e)),
                           Vec3(e, e, plane_z(-0.5, e, e)), Vec3(-e, e, plane_z(-0.5, -e, e)), 1));
  const RenderParams p = local_aa(8);
  auto ps = prepare_scene(s, p);
  ASSERT_TRUE(ps.ok());
  const BandResult r = render_band(**ps, Band{0, 40}, p);
  // Reference: the red fraction of each pixel from 256 x 256 point samples.
  const CameraFrame& cam = (*ps)->camera;
  int mixed = 0;
  double worst = 0;
  for (int j = 0; j < 40; j += 3) {
    for (int i = 0; i < 48; ++i) {
      const float* px = r.pixels.pixel(i, j);
      EXPECT_NEAR(px[0] + px[1], 1.0, 1e-5) << i << "," << j;  // fully covered
      int red = 0;
      const int m = 256;
      for (int b = 0; b < m; ++b) {
        for (int a = 0; a < m; ++a) {
          const Ray ray{cam.from, cam.direction(i + (a + 0.5) / m, j + (b + 0.5) / m)};
          // Red is in front where its z is larger (nearer the eye at z = 10).
          const double t0 = ray.dir.z, x0 = ray.origin.x, y0 = ray.origin.y;
          auto z_at = [&](double slope) {
            // Intersect ray with z = slope (x - 0.3 y - 0.2).
            const double den = t0 - slope * (ray.dir.x - 0.3 * ray.dir.y);
            const double t = (slope * (x0 - 0.3 * y0 - 0.2) - ray.origin.z) / den;
            return ray.origin.z + t * t0;
          };
          if (z_at(0.5) > z_at(-0.5)) ++red;
        }
      }
      const double want = static_cast<double>(red) / (m * m);
      if (want > 0 && want < 1) ++mixed;
      worst = std::max(worst, std::abs(px[0] - want));
    }
  }
  EXPECT_GT(mixed, 8);
  // 1/m of sampling error in the reference, plus rounding.
  EXPECT_LT(worst, 2.0 / 256) << "red fraction along the intersection line";
}

// Curved bodies: bisection finds the true silhouette inside the bounding
// polyhedron's span; the error is that of the trapezoidal rule and of the
// bisection tolerance, and falls with the sub-scanlines.
TEST(Multiscan, SphereSilhouetteCoverage) {
  double prev = 1e9;
  for (int n : {1, 4, 16}) {
    Scene s = coverage_scene(32, 32);
    Object ball;
    ball.shape = Sphere{Vec3(0.13, -0.21, 0), 2.1};
    s.objects.push_back(ball);
    auto ps = prepare_scene(s, local_aa(n));
    ASSERT_TRUE(ps.ok());
    const BandResult r = render_band(**ps, Band{0, 32}, local_aa(n));
    const CameraFrame& cam = (*ps)->camera;
    double sum2 = 0, worst = 0, total_err = 0;
    int edge = 0;
    for (int j = 0; j < 32; ++j) {
      for (int i = 0; i < 32; ++i) {
        const int m = 64;
        int in = 0;
        for (int b = 0; b < m; ++b) {
          for (int a = 0; a < m; ++a) {
            const Ray ray{cam.from, cam.direction(i + (a + 0.5) / m, j + (b + 0.5) / m)};
            const Vec3 oc = ray.origin - Vec3(0.13, -0.21, 0);
            const double bq = glm::dot(oc, ray.dir), cq = glm::dot(oc, oc) - 2.1 * 2.1;
            if (bq * bq - cq > 0) ++in;
          }
        }
        const double want = static_cast<double>(in) / (m * m);
        const double err = r.pixels.pixel(i, j)[0] - want;
        if (want > 0 && want < 1) {
          ++edge;
          sum2 += err * err;
          worst = std::max(worst, std::abs(err));
          total_err += err;
        } else {
          EXPECT_NEAR(err, 0.0, 1e-5) << i << "," << j << " aa " << n;
        }
      }
    }
    const double rms = std::sqrt(sum2 / edge);
    std::printf("sphere aa %2d: %d edge pixels, rms %.4f, max %.4f, total area error %.4f px\n",
                n, edge, rms, worst, total_err);
    EXPECT_LT(worst, 0.5 / n + 2.0 / 64) << "aa " << n;
    EXPECT_LT(rms, prev);
    prev = rms;
  }
}

// The outlines of spheres and cones on each sub-scanline are found exactly
// (silhouette_guess: the eye's pencil), not to the bisection's 1/64 pixel:
// each pixel then equals the trapezoidal rule over the sub-scanlines of
// the exact lengths covered, which bisection of the ray tracer's own hit
// test (to 1e-12 pixel) gives here. A sphere, a tilted open cylinder
// (whose outline includes its rims) and a cone, apart from each other.
TEST(Multiscan, CurvedOutlinesAreExactOnEachSubScanline) {
  const int n = 4, w = 40, h = 32;
  Scene s = coverage_scene(w, h);
  std::vector<Shape> shapes = {Sphere{Vec3(-2.0, 0.6, 0), 1.1},
                               Cone{Vec3(0.6, -1.6, -0.5), 0.5, Vec3(1.9, 1.2, 1.0), 0.5, false},
                               Cone{Vec3(2.6, -1.8, 0), 0.6, Vec3(3.2, -0.2, 0.8), 0.0, false}};
  for (const Shape& shape : shapes) {
    Object o;
    o.shape = shape;
    s.objects.push_back(o);
  }
  auto ps = prepare_scene(s, local_aa(n));
  ASSERT_TRUE(ps.ok());
  const BandResult r = render_band(**ps, Band{0, h}, local_aa(n));
  const CameraFrame& cam = (*ps)->camera;
  const PrimitiveSet& prims = (*ps)->prims;
  auto covered = [&](double x, double y) {
    const Ray ray{cam.from, cam.direction(x, y)};
    for (int p = 0; p < static_cast<int>(prims.prims.size()); ++p) {
      if (intersect_nearest(prims, p, ray, 0.0, kInf)) return true;
    }
    return false;
  };
  // Per sub-scanline: where `covered` changes, by a scan at 1/32 pixel and
  // bisection to 1e-12; then each pixel's covered length.
  std::vector<std::vector<double>> length(n * h + 1, std::vector<double>(w, 0.0));
  for (int g = 0; g <= n * h; ++g) {
    const double y = static_cast<double>(g) / n;
    double x0 = 0;
    bool in = covered(1e-9, y);
    auto add = [&](double a, double b) {
      for (int i = 0; i < w; ++i) {
        length[g][i] += std::max(0.0, std::min(b, i + 1.0) - std::max(a, double(i)));
      }
    };
    for (int k = 1; k <= 32 * w; ++k) {
      double xr = k / 32.0;
      if (k == 32 * w) xr -= 1e-9;
      if (covered(xr, y) == in) continue;
      double lo = xr - 1 / 32.0, hi = xr;
      while (hi - lo > 1e-12) (covered(0.5 * (lo + hi), y) == in ? lo : hi) = 0.5 * (lo + hi);
      if (in) add(x0, hi);
      x0 = hi;
      in = !in;
    }
    if (in) add(x0, w);
  }
  double sum2 = 0, worst = 0;
  int edge = 0, exact = 0;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      double want = 0;
      for (int k = 0; k <= n; ++k) {
        want += (k == 0 || k == n ? 0.5 : 1.0) / n * length[j * n + k][i];
      }
      if (!(want > 0 && want < 1)) continue;
      const double err = std::abs(r.pixels.pixel(i, j)[0] - want);
      ++edge;
      exact += err < 1e-5;
      sum2 += err * err;
      worst = std::max(worst, err);
    }
  }
  std::printf("curved outlines: %d edge pixels, %d exact to 1e-5, rms %.2e, max %.2e\n", edge,
              exact, std::sqrt(sum2 / edge), worst);
  EXPECT_GT(edge, 100);
  EXPECT_GT(exact, 0.95 * edge);
}

// The failure mode of sampling (METHOD.md §6): a sphere much smaller than
// a pixel. Its bounding polyhedron's span is exact, and each pixel piece of
// it gets a sample at its midpoint, so the sphere is found where a
// sub-scanline crosses it; its area is measured, not lost, once the
// sub-scanlines are closer than its diameter.
TEST(Multiscan, SubPixelSpheresAreMeasured) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> pos(-2.0, 2.0);
  for (int n : {4, 16}) {
    Scene s = coverage_scene(64, 64);
    const double radius = 0.02;  // 0.35 pixel in diameter here
    double want = 0;
    for (int k = 0; k < 40; ++k) {
      Object ball;
      ball.shape = Sphere{Vec3(pos(rng), pos(rng), 0), radius};
      s.objects.push_back(ball);
    }
    auto ps = prepare_scene(s, local_aa(n));
    ASSERT_TRUE(ps.ok());
    const CameraFrame& cam = (*ps)->camera;
    // Image-space area of one sphere: radius in pixels from the focal length.
    const double px_per_unit = cam.height / (2.0 * cam.tan_half * 10.0);
    want = 40 * M_PI * std::pow(radius * px_per_unit, 2);
    const BandResult r = render_band(**ps, Band{0, 64}, local_aa(n));
    double got = 0;
    for (int j = 0; j < 64; ++j) {
      for (int i = 0; i < 64; ++i) got += r.pixels.pixel(i, j)[0];
    }
    std::printf("40 spheres of %.2f px: aa %2d measures %.3f px^2 of %.3f (%.0f%%)\n",
                2 * radius * px_per_unit, n, got, want, 100 * got / want);
    if (n == 16) {
      EXPECT_NEAR(got / want, 1.0, 0.25);
    }
    EXPECT_GT(got, 0.0);
  }
}

// The largest channel difference between `got` and the ray tracer with
// 32 x 32 eye rays per pixel through the whole search.
double max_error_against_rays(const Scene& s, const Image& got) {
  RenderParams ref;
  ref.method = Method::kRaytrace;
  ref.spp = 32;
  auto want = render_image(s, ref);
  EXPECT_TRUE(want.ok());
  if (!want.ok()) return 1e9;
  double worst = 0;
  for (int j = 0; j < s.camera.height; ++j) {
    for (int i = 0; i < s.camera.width; ++i) {
      for (int c = 0; c < 3; ++c) {
        worst = std::max(worst, std::abs(static_cast<double>(got.pixel(i, j)[c]) -
                                         want->pixels.pixel(i, j)[c]));
      }
    }
  }
  return worst;
}

// Inside a curved body's bounding polyhedron, the first surface at a sample
// is searched among the primitives whose faces' outlines hold the sample
// (docs/multiscan.md). Bodies sunk into a polygon (which lies inside their
// boxes), a small sphere in front of a large one, and a cylinder crossing
// both: each surface has its own colour, ambient only, so a pixel is the
// sum of colour times area, and a surface missed by the search would move
// a whole pixel's worth of colour. Truth: 32 x 32 eye rays per pixel
// through the whole search.
TEST(Multiscan, FirstHitAmongOutlinesFindsEverySurface) {
  Scene s = coverage_scene(40, 40);
  s.materials.resize(4);
  s.materials[0].color = Color(1, 0, 0);
  s.materials[1].color = Color(0, 1, 0);
  s.materials[2].color = Color(0, 0, 1);
  s.materials[3].color = Color(1, 1, 1);
  s.objects.push_back(quad(Vec3(-3, -3, 0), Vec3(3, -3, 0), Vec3(3, 3, 0), Vec3(-3, 3, 0), 0));
  auto add = [&](Shape shape, int material) {
    Object o;
    o.shape = shape;
    o.material = material;
    s.objects.push_back(o);
  };
  add(Sphere{Vec3(-1.2, -0.9, 0.2), 1.3}, 1);
  add(Sphere{Vec3(-0.6, -0.4, 1.9), 0.35}, 2);
  add(Sphere{Vec3(1.4, 1.1, -0.5), 1.0}, 2);
  add(Cone{Vec3(-2.5, 1.6, -0.3), 0.3, Vec3(2.5, 0.2, 0.6), 0.3}, 3);
  const RenderParams p = local_aa(4);
  auto ps = prepare_scene(s, p);
  ASSERT_TRUE(ps.ok());
  const BandResult r = render_band(**ps, Band{0, 40}, p);
  const double worst = max_error_against_rays(s, r.pixels);
  std::printf("surfaces in boxes, aa 4 against 32 x 32 rays: max error %.4f\n", worst);
  // The coverage error of 4 sub-scanlines on a curved edge (as in
  // SphereSilhouetteCoverage), not a missed surface (an error near 1).
  EXPECT_LT(worst, 0.5 / 4 + 1.0 / 32);
}

// A surface that lies wholly between two samples of a curved run, where the
// samples see two other surfaces: the bisection between them must find it
// (docs/multiscan.md). Two rows of upright cylinders (vertical silhouettes,
// so coverage along a sub-scanline is exact to the bisection's 1/64 pixel):
// in the first, gaps of 0.1 to 0.5 pixel show a white floor; in the second,
// the cylinders overlap and a blue cylinder 0.4 pixel wide stands in front
// of each junction. Ambient only, so a pixel is colour times area. Against
// 32 x 32 eye rays per pixel; a surface missed between samples moves up to
// its width in pixels (0.4 to 0.5 here).
TEST(Multiscan, SurfacesBetweenTwoSamplesAreFound) {
  constexpr int kW = 48, kH = 16;
  // A pixel's width at depth 10 (the cylinders' axes): the 40 degree angle
  // spans the image's height.
  const double px = 2.0 * std::tan(glm::radians(20.0)) * 10.0 / kH;
  for (const bool gaps : {true, false}) {
    Scene s = coverage_scene(kW, kH);
    s.materials.resize(4);
    s.materials[0].color = Color(1, 0, 0);
    s.materials[1].color = Color(0, 1, 0);
    s.materials[2].color = Color(0, 0, 1);
    s.materials[3].color = Color(1, 1, 1);
    s.objects.push_back(quad(Vec3(-20, -9, -4), Vec3(20, -9, -4), Vec3(20, 9, -4), Vec3(-20, 9, -4), 3));
    auto upright = [&](double x, double z, double r, int material) {
      Object o;
      o.shape = Cone{Vec3(x, -4, z), r, Vec3(x, 4, z), r};
      o.material = material;
      s.objects.push_back(o);
    };
    // Radius 3 pixels; the k-th gap (or overlap) at a different phase
    // against the pixel grid.
    const double r = 3 * px;
    double x = -21.5 * px;
    for (int k = 0; k < 7; ++k) {
      const double axis = x + r;
      upright(axis, 0, r, k % 2);
      if (gaps) {
        x += 2 * r + (0.1 + 0.4 * k / 6.0) * px;
      } else {
        // Overlapping by half a pixel: the junction is the line where the
        // two surfaces meet, midway between the axes and h nearer the eye;
        // it projects onto the axes' plane (depth 10) at `junction`. The
        // thin cylinder, at depth 8, is placed to project near it.
        const double d = 2 * r - 0.5 * px;
        x += d;
        const double h = std::sqrt(r * r - 0.25 * d * d);
        const double junction = (axis + 0.5 * d) * 10.0 / (10.0 - h);
        if (k < 6) upright((junction + (0.05 * k - 0.15) * px) * 0.8, 2, 0.2 * px * 0.8, 2);
      }
    }
    auto got = render_image(s, local_aa(4));
    ASSERT_TRUE(got.ok());
    const double worst = max_error_against_rays(s, got->pixels);
    std::printf("%s between samples, aa 4 against 32 x 32 rays: max error %.4f\n",
                gaps ? "gaps" : "thin cylinders", worst);
    // Two bisected edges (1/64 each) and the reference's 1/32.
    EXPECT_LT(worst, 2.0 / 64 + 1.0 / 32) << (gaps ? "gaps" : "thin cylinders");
  }
}

// RMSE of `scene` at 96x96 rendered with local_aa(n), for each n, against
// the supersampled ray tracer (--spp 16); empty if a render failed.
std::vector<double> errors_against_supersampled(Scene scene, std::initializer_list<int> ns,
                                                const char* name) {
  scene.camera.width = 96;
  scene.camera.height = 96;
  RenderParams ref;
  ref.method = Method::kRaytrace;
  ref.spp = 16;
  auto want = render_image(scene, ref);
  if (!want.ok()) return {};
  std::vector<double> errs;
  for (int n : ns) {
    auto r = render_image(scene, local_aa(n));
    if (!r.ok()) return {};
    double s2 = 0;
    for (size_t k = 0; k < r->pixels.rgb.size(); ++k) {
      const double d = r->pixels.rgb[k] - want->pixels.rgb[k];
      s2 += d * d;
    }
    errs.push_back(std::sqrt(s2 / static_cast<double>(r->pixels.rgb.size())));
    std::printf("%s 96x96: aa %2d rmse %.5f\n", name, n, errs.back());
  }
  return errs;
}

// Multi-scanning converges to the supersampled ray tracer on the paper's
// scene (d): mirrors, prisms, shadows, curved silhouettes.
TEST(Multiscan, ConvergesToSupersampledRayTracer) {
  auto scene = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json");
  ASSERT_TRUE(scene.ok());
  const std::vector<double> errs = errors_against_supersampled(*scene, {0, 1, 4, 16}, "scene (d)");
  ASSERT_EQ(errs.size(), 4u);
  EXPECT_LT(errs[2], 0.5 * errs[0]);
  EXPECT_LT(errs[3], errs[2]);
}

// Inside glass, the refracted image's detail is resolved as N grows: the
// corner interpolation's contrast threshold falls with N (kContrast / (N /
// 4), pixel_samples.cpp), so the error keeps falling where a fixed
// threshold left a floor. SPD mount (its glass spheres refract the
// terrain), 96x96, against the supersampled ray tracer: with the fixed
// 0.05, aa 16 had 0.79 of aa 8's error (0.0030 against 0.0039); now 0.42.
TEST(Multiscan, RefractedDetailConvergesAsNGrows) {
  auto scene = load_scene(LOCUS_SHARED_DIR "/spd/def/mount.nff");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  const std::vector<double> errs = errors_against_supersampled(*scene, {4, 8, 16}, "mount");
  ASSERT_EQ(errs.size(), 3u);
  EXPECT_LT(errs[1], 0.6 * errs[0]);
  EXPECT_LT(errs[2], 0.6 * errs[1]);
}

// At N = 1 a traced pixel its corners do not settle traces its centre alone
// and weighs it with the corners (PixelSamples::centre_only_), where N = 2
// traces three or four points inside it. On scene (d) at 96x96 (mirrored
// and glass spheres, prisms) the reflected and refracted rays of --aa 1 are
// 0.51 of --aa 2's (0.95 with the fine grid at N = 1 too), and the error
// against the supersampled ray tracer is 0.59 of point sampling's (RMSE
// 0.0217; 0.0203 with the fine grid).
TEST(Multiscan, OneSubScanlineTracesTheCentreOfARefinedPixel) {
  auto scene = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json");
  ASSERT_TRUE(scene.ok());
  scene->camera.width = 96;
  scene->camera.height = 96;
  uint64_t secondary[2];
  for (int n : {1, 2}) {
    auto ps = prepare_scene(*scene, local_aa(n));
    ASSERT_TRUE(ps.ok());
    const BandResult r = render_band(**ps, Band{0, 96}, local_aa(n));
    secondary[n - 1] = r.stats.rays_reflected + r.stats.rays_refracted;
    ASSERT_GT(r.stats.pixels_ray_traced, 500u);
  }
  std::printf("scene (d) 96x96: reflected and refracted rays, aa 1 %llu, aa 2 %llu\n",
              static_cast<unsigned long long>(secondary[0]),
              static_cast<unsigned long long>(secondary[1]));
  EXPECT_LT(static_cast<double>(secondary[0]), 0.6 * static_cast<double>(secondary[1]));
  const std::vector<double> errs = errors_against_supersampled(*scene, {0, 1, 2}, "scene (d)");
  ASSERT_EQ(errs.size(), 3u);
  EXPECT_LT(errs[1], 0.7 * errs[0]);
}

TEST(Multiscan, BandsAndThreadsBitIdentical) {
  for (const char* path : {LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json",
                           LOCUS_SOURCE_DIR "/scenes/paper/a_glass.json",
                           LOCUS_SHARED_DIR "/spd/s1/gears.nff"}) {
    for (Boxes boxes : {Boxes::kNone, Boxes::kEyeShadow}) {
      RenderParams p = local_aa(4, boxes);
      expect_bands_bit_identical(path, p);
      p.threads = 1;
      expect_bands_bit_identical(path, p);
    }
  }
}

TEST(Multiscan, RejectsOutOfRangeAndMixedSettings) {
  Scene s = coverage_scene(8, 8);
  RenderParams p = local_aa(kMaxAa + 1);
  EXPECT_FALSE(prepare_scene(s, p).ok());
  p = local_aa(-1);
  EXPECT_FALSE(prepare_scene(s, p).ok());
  p = local_aa(4);
  p.spp = 2;
  EXPECT_FALSE(prepare_scene(s, p).ok());
  p = RenderParams{};
  p.aa = 2;  // the ray tracer
  EXPECT_FALSE(prepare_scene(s, p).ok());
}

}  // namespace
}  // namespace locus
