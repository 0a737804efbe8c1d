// Helpers shared by the tests that hold the local method (configurations
// II-IV) to the ray tracer's image: the scenes to compare on, and where a
// pixel may differ because either answer is right.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "common/base/image.h"
#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scan/scanline.h"
#include "common/scene/scene_io.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace testing_util {

// Configuration IV (--method local --boxes eye+shadow) with `aa`
// sub-scanlines per row, on `threads` threads.
inline RenderParams config_iv_params(int aa, int threads) {
  RenderParams p;
  p.method = Method::kLocal;
  p.boxes = Boxes::kEyeShadow;
  p.aa = aa;
  p.threads = threads;
  return p;
}

// The ray tracer (--method raytrace) with spp x spp samples a pixel.
inline RenderParams raytrace_params(int spp) {
  RenderParams p;
  p.method = Method::kRaytrace;
  p.spp = spp;
  return p;
}

// Configuration IV on one thread with its shadows by rays (--shadows rays).
inline RenderParams shadow_rays_params(int aa) {
  RenderParams p = config_iv_params(aa, 1);
  p.shadows = ShadowPass::kRays;
  return p;
}

// Distance from pixel centre (x, y) to the nearest projected face edge of
// the scanline pass.
// Renders the scene at 64 x 50 whole and split into 2, 3, 7 and 50 bands;
// every band's rows must be bit-identical to the same rows of the whole.
inline void expect_bands_bit_identical(const std::string& path, const RenderParams& p) {
  auto scene = load_scene(path);
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  scene->camera.width = 64;
  scene->camera.height = 50;
  auto prepared = prepare_scene(*scene, p);
  ASSERT_TRUE(prepared.ok()) << prepared.status().message();
  const BandResult whole = render_band(**prepared, Band{0, 50}, p);
  for (int bands : {2, 3, 7, 50}) {
    for (int b = 0; b < bands; ++b) {
      const Band band{b * 50 / bands, (b + 1) * 50 / bands};
      const BandResult part = render_band(**prepared, band, p);
      for (int y = band.y0; y < band.y1; ++y) {
        ASSERT_EQ(0, std::memcmp(whole.pixels.pixel(0, y), part.pixels.pixel(0, y - band.y0),
                                 sizeof(float) * 3 * 64))
            << path << ": " << bands << " bands, row " << y;
      }
    }
  }
}

inline double distance_to_edge(const ScanScene& scan, double x, double y) {
  double best = 1e300;
  for (const ScanFace& f : scan.faces) {
    const size_t n = f.outline.size();
    for (size_t k = 0; k < n; ++k) {
      const Vec2 a = f.outline[k], b = f.outline[(k + 1) % n];
      const Vec2 ab = b - a, ap = Vec2(x, y) - a;
      const double len2 = glm::dot(ab, ab);
      const double t = len2 > 0 ? std::clamp(glm::dot(ap, ab) / len2, 0.0, 1.0) : 0.0;
      best = std::min(best, glm::length(ap - t * ab));
    }
  }
  return best;
}

// Every SPD scene of sizes s1 and s2 and every scene in scenes/.
inline std::vector<std::string> agreement_scenes() {
  namespace fs = std::filesystem;
  std::vector<std::string> out;
  for (const char* dir : {LOCUS_SHARED_DIR "/spd/s1", LOCUS_SHARED_DIR "/spd/s2",
                          LOCUS_SOURCE_DIR "/scenes/paper", LOCUS_SOURCE_DIR "/scenes/simple"}) {
    if (!fs::exists(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".nff" || ext == ".json") out.push_back(e.path().string());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A scene with a camera, one light beside the eye and two diffuse
// materials (0 red, 1 green), for hand-made hard cases.
inline Scene camera_scene(const Vec3& from, const Vec3& at, double angle, int w, int h) {
  Scene s;
  s.has_camera = true;
  s.camera.from = from;
  s.camera.at = at;
  s.camera.up = Vec3(0, 1, 0);
  s.camera.angle = angle;
  s.camera.width = w;
  s.camera.height = h;
  s.background = Color(0.2, 0.4, 0.9);
  s.lights.push_back(Light{from + Vec3(1, 3, 0.5), std::nullopt});
  Material a, b;
  a.color = Color(0.9, 0.3, 0.2);
  b.color = Color(0.2, 0.8, 0.3);
  s.materials = {a, b};
  return s;
}

inline Object quad(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, int material) {
  Object o;
  o.shape = Polygon{{a, b, c, d}};
  o.material = material;
  return o;
}

// The largest difference of any channel of any pixel of two images of one size.
inline double max_difference(const Image& x, const Image& y) {
  double m = 0;
  for (int j = 0; j < x.height; ++j)
    for (int i = 0; i < x.width; ++i)
      for (int c = 0; c < 3; ++c)
        m = std::max(m, static_cast<double>(std::abs(x.pixel(i, j)[c] - y.pixel(i, j)[c])));
  return m;
}

inline int max_diff8(const float* a, const float* b) {
  int diff = 0;
  for (int c = 0; c < 3; ++c) diff = std::max(diff, std::abs(quantize8(a[c]) - quantize8(b[c])));
  return diff;
}

// Pixels where a local render may differ from the ray tracer by more than
// 2/255, because either answer is right there.
struct Exceptions {
  int edge = 0;      // centre within 1e-6 pixel of a projected face edge
  int boundary = 0;  // on a shadow boundary: the ray tracer itself gives the
                     // local value 1e-6 pixel away from the centre
};

// The ray tracer's value at image point (x, y), point sampled.
inline Color trace_at(const PreparedScene& ps, double x, double y) {
  Stats stats;
  Tracer tracer(ps, stats);
  return tracer.trace(Ray{ps.camera.from, ps.camera.direction(x, y)}, ps.camera.hither, 1, 1.0,
                      nullptr);
}

// Renders `s` with the ray tracer (--boxes eye+shadow) and with `local`
// (method local), point sampled, and expects the same 8-bit image within
// 2/255 but at excepted pixels, which it counts.
inline Exceptions expect_agreement(const Scene& s, const RenderParams& local,
                                   const std::string& what) {
  Exceptions ex;
  RenderParams rp;
  rp.threads = local.threads;
  rp.tess_tol = local.tess_tol;  // the same triangles
  auto ref_ps = prepare_scene(s, rp);
  auto loc_ps = prepare_scene(s, local);
  EXPECT_TRUE(ref_ps.ok() && loc_ps.ok()) << what;
  if (!ref_ps.ok() || !loc_ps.ok()) return ex;
  const int w = s.camera.width, h = s.camera.height;
  const BandResult ref = render_band(**ref_ps, Band{0, h}, rp);
  const BandResult loc = render_band(**loc_ps, Band{0, h}, local);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float* lp = loc.pixels.pixel(x, y);
      const int diff = max_diff8(ref.pixels.pixel(x, y), lp);
      if (diff <= 2) continue;
      if (distance_to_edge(*(*loc_ps)->scan, x + 0.5, y + 0.5) < 1e-6) {
        ++ex.edge;
        continue;
      }
      bool boundary = false;
      for (int k = 0; k < 8 && !boundary; ++k) {
        const double ang = k * 0.25 * 3.14159265358979323846;
        const Color c =
            trace_at(**ref_ps, x + 0.5 + 1e-6 * std::cos(ang), y + 0.5 + 1e-6 * std::sin(ang));
        const float v[3] = {static_cast<float>(c.x), static_cast<float>(c.y),
                            static_cast<float>(c.z)};
        boundary = max_diff8(v, lp) <= 2;
      }
      if (boundary) {
        ++ex.boundary;
        continue;
      }
      ADD_FAILURE() << what << " pixel " << x << "," << y << " differs by " << diff << "/255";
      return ex;
    }
  }
  return ex;
}

}  // namespace testing_util
}  // namespace locus
