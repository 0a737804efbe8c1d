// Stability under scale and under motion: the same scene scaled by 1e-3 and
// 1e5 gives the same image, and a camera moving 1e-4 pixel per frame gives
// frames that change smoothly, with no flicker. tests/stability/README.md
// lists the expectations and bounds.
#include <gtest/gtest.h>

#include <cmath>
#include <variant>

#include "tests/stability/stability.h"

namespace locus {
namespace stability {
namespace {

// A scene with something of everything: a checkerboard floor, a box, a
// prism, a diffuse, a mirror and a glass sphere, two lights.
Scene mixed_scene(int w, int h) {
  Scene s = camera_scene(Vec3(1.5, 2.6, 6.5), Vec3(0, 0.7, 0), 42, w, h);
  s.materials = {diffuse(Color(0.85)), diffuse(Color(0.25)), diffuse(Color(0.9, 0.3, 0.2)), mirror(0.8),
                 glass(1.5, 0.9), diffuse(Color(0.2, 0.8, 0.3))};
  s.lights = {Light{Vec3(3, 6, 4), std::nullopt}, Light{Vec3(-4, 3, 2), std::nullopt}};
  const int n = 6;
  const double half = 4, step = 2 * half / n;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x0 = -half + i * step, z0 = -half + j * step;
      s.objects.push_back(quad(Vec3(x0, 0, z0 + step), Vec3(x0 + step, 0, z0 + step),
                               Vec3(x0 + step, 0, z0), Vec3(x0, 0, z0), (i + j) % 2));
    }
  }
  s.objects.push_back(box(Vec3(-2, 0, -1.5), Vec3(-0.8, 1.3, -0.4), 2));
  s.objects.push_back(object(make_prism(5, 0.5, Vec3(1.6, 0, -1.4), Vec3(1.6, 1.6, -1.4), 10), 5));
  s.objects.push_back(sphere(Vec3(0.1, 0.8, -0.3), 0.8, 3));
  s.objects.push_back(sphere(Vec3(1.3, 0.45, 1.1), 0.45, 4));
  s.objects.push_back(sphere(Vec3(-1.2, 0.35, 1.0), 0.35, 5));
  return s;
}

// Every length multiplied by k: camera, hither, lights, geometry.
Scene scaled(Scene s, double k) {
  s.camera.from *= k;
  s.camera.at *= k;
  s.camera.hither *= k;
  for (Light& l : s.lights) l.position *= k;
  for (Object& o : s.objects) {
    if (auto* sp = std::get_if<Sphere>(&o.shape)) {
      sp->center *= k;
      sp->radius *= k;
    } else if (auto* pg = std::get_if<Polygon>(&o.shape)) {
      for (Vec3& v : pg->vertices) v *= k;
    } else if (auto* ph = std::get_if<Polyhedron>(&o.shape)) {
      for (Vec3& v : ph->vertices) v *= k;
    } else {
      ADD_FAILURE() << "scaled(): shape not handled";
    }
  }
  return s;
}

// The scene at scale 1 passes every check of the suite; scaled by 1e-3 and
// by 1e5 (lengths from 1e-3 to 1e6), every mode must give its own scale-1
// image: offsets of secondary rays, shadow-volume slack, coincidence
// tolerances and bisection are all relative, so only rounding may differ.
// Point modes: within 2/255 but at centres within 1e-6 px of an edge.
// aa 4: within 1/255 (a bisection step of 1/64 px that rounding moves
// changes a pixel by at most contrast / 64 / 4 on one sub-scanline).
TEST(StabilityScale, SameImageAtScales1e_3And1e5) {
  const Scene base = mixed_scene(64, 64);
  const CaseResult r1 = check_case(base, Bounds{}, "scale 1");
  auto ps_scan = prepare_scene(base, params(Method::kLocal, Boxes::kNone, 0, 1));
  ASSERT_TRUE(ps_scan.ok());
  for (double k : {1e-3, 1e5}) {
    const Scene s = scaled(base, k);
    for (const ModeResult& m1 : r1.modes) {
      const Image img = render_or_fail(s, m1.params, "scale " + std::to_string(k) + " " + m1.name);
      const bool point = m1.params.aa == 0 && m1.params.spp == 1;
      int nonfinite = count_nonfinite(img), over = 0, excepted = 0;
      double worst = 0;
      for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
          const double d = chan_max_abs(img.pixel(x, y), m1.img.pixel(x, y));
          worst = std::max(worst, d);
          if (point) {
            if (testing_util::max_diff8(img.pixel(x, y), m1.img.pixel(x, y)) <= 2) continue;
            if (distance_to_edge(*(*ps_scan)->scan, x + 0.5, y + 0.5) < 1e-6) {
              ++excepted;
              continue;
            }
            ++over;
          } else if (d > 1.0 / 255) {
            ++over;
          }
        }
      }
      std::printf("[scale %g] %-7s vs scale 1: max diff %.2e, over bound %d, edge exceptions %d, "
                  "nonfinite %d\n", k, m1.name.c_str(), worst, over, excepted, nonfinite);
      EXPECT_EQ(nonfinite, 0) << "scale " << k << " " << m1.name;
      EXPECT_EQ(over, 0) << "scale " << k << " " << m1.name << ": max diff " << worst;
    }
  }
}

// A camera moving 1e-4 pixel per frame (measured at the look-at point),
// diagonally, over 9 frames at --aa 4. The exact image moves by 1e-4 px, so
// a pixel with an edge of contrast C in it changes by about C * 1e-4 per
// frame. The documented approximations of multi-scanning change some
// pixels by steps instead, and those steps are what is bounded:
//  - pixels of flat diffuse faces: polygon edges and shadow-volume edges
//    are exact intervals, they move continuously. The shadows of curved
//    occluders are located by bisection on a fixed grid of 1/64 px, so when
//    one crosses a grid cell that sub-scanline's piece jumps by 1/64 px: at
//    most C / 64 * 1/4 per sub-scanline. Bound 2 such steps (C <= 1):
//    1/128;
//  - pixels of ray-traced spans (mirrors, glass, curved bodies): their
//    samples are points, 1 per pixel per sub-scanline, 4 where neighbours
//    differ by more than 0.05 (pixel_samples.cpp). When a reflected edge of
//    contrast C crosses one of the 4 sample points, the pixel jumps by
//    C * 1/4 (the sample's share of the piece) * 1/4 (the sub-scanline's
//    weight); with C <= 1 in this scene: 1/16. Unrefined samples straddle
//    edges under 0.05: 0.05 / 4.
// No flicker: the second difference f[k+1] - 2 f[k] + f[k-1] obeys the same
// bounds (a step is not undone in the next frame more than a step allows),
// and steps are rare: at most 1% of the pixel changes between frames exceed
// 1e-3.
TEST(StabilityFlicker, CameraMoving1e_4PixelPerFrame) {
  const int w = 64, h = 64, frames = 9;
  Scene s = mixed_scene(w, h);
  const Camera cam0 = s.camera;
  const CameraFrame f(cam0);
  const double dist = glm::length(cam0.at - cam0.from);
  const double pixel = 2 * dist * f.tan_half / h;  // one pixel at the look-at point, world units
  const Vec3 step = 1e-4 * pixel * glm::normalize(f.u + 0.6 * f.v);
  std::vector<Image> img;
  const RenderParams p = params(Method::kLocal, Boxes::kEyeShadow, kAa, 1);
  auto ps0 = prepare_scene(s, p);
  ASSERT_TRUE(ps0.ok());
  const std::vector<char> traced = traced_pixels(**ps0);
  for (int k = 0; k < frames; ++k) {
    s.camera.from = cam0.from + double(k) * step;
    s.camera.at = cam0.at + double(k) * step;
    img.push_back(render_or_fail(s, p, "frame " + std::to_string(k)));
    EXPECT_EQ(count_nonfinite(img.back()), 0) << "frame " << k;
    dump("flicker", std::to_string(k), img.back());
  }
  const double bound_flat = 1.0 / 128, bound_traced = 1.0 / 16;
  double worst[2] = {0, 0}, worst2[2] = {0, 0};
  int steps = 0, pairs = 0, wx[2] = {-1, -1}, wy[2] = {-1, -1}, wk[2] = {-1, -1};
  for (int k = 1; k < frames; ++k) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int t = traced[y * w + x] ? 1 : 0;
        const double d = chan_max_abs(img[k].pixel(x, y), img[k - 1].pixel(x, y));
        ++pairs;
        steps += d > 1e-3;
        if (d > worst[t]) worst[t] = d, wx[t] = x, wy[t] = y, wk[t] = k;
        if (k + 1 < frames) {
          double d2 = 0;
          for (int c = 0; c < 3; ++c) {
            d2 = std::max(d2, std::abs(static_cast<double>(img[k + 1].pixel(x, y)[c]) -
                                       2.0 * img[k].pixel(x, y)[c] + img[k - 1].pixel(x, y)[c]));
          }
          worst2[t] = std::max(worst2[t], d2);
        }
      }
    }
  }
  std::printf("[flicker] %d frames, 1e-4 px each. Flat pixels: largest change %.2e (pixel %d,%d, "
              "frame %d), second difference %.2e, bound %.4f. Ray-traced pixels: largest change "
              "%.2e (pixel %d,%d, frame %d), second difference %.2e, bound %.4f. Changes over 1e-3: "
              "%d of %d\n",
              frames, worst[0], wx[0], wy[0], wk[0], worst2[0], bound_flat, worst[1], wx[1], wy[1],
              wk[1], worst2[1], bound_traced, steps, pairs);
  EXPECT_LE(worst[0], bound_flat) << "flat pixel " << wx[0] << "," << wy[0] << ", frame " << wk[0];
  EXPECT_LE(worst2[0], bound_flat);
  EXPECT_LE(worst[1], bound_traced) << "traced pixel " << wx[1] << "," << wy[1] << ", frame " << wk[1];
  EXPECT_LE(worst2[1], bound_traced);
  EXPECT_LE(steps, pairs / 100);
}

}  // namespace
}  // namespace stability
}  // namespace locus
