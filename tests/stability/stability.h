// The stability suite (issue #6 item 6; tests/stability/README.md): scenes
// built to break scanline, shadow-volume and ray-tracing methods. Every case
// goes through check_case(), which renders the scene in every mode and
// checks, numerically:
//
//  1. no NaN or Inf in any image;
//  2. agreement with the reference:
//     - point-sampled modes (raytrace --boxes eye+shadow, local II, III and
//       IV at --aa 0) against configuration I (raytrace --boxes none,
//       --spp 1): 8-bit values within 2/255, except at pixels where either
//       answer is right: configuration I sampled 1e-6 px away from the
//       centre, in one of 8 directions, gives the mode's value (the centre
//       lies on an edge, counted as an edge exception when it is within
//       1e-6 px of a projected face edge, or on a shadow boundary). A value
//       found on neither side (what lies behind two faces sharing an edge)
//       is a failure, as is every other pixel; the exceptions are counted
//       and bounded per case;
//     - configuration I against raytrace --spp 16 (the reference image of
//       the analytic scene): a point sample lies within the range of the
//       function over its pixel, so |I - ref| <= range3(ref) + point_tol,
//       range3 being the largest channel range of ref over the 3x3
//       neighbourhood. Where detail finer than a pixel hides from the 3x3
//       averages, the range inside the pixel (16 x 16 point samples of
//       configuration I) takes its place ("relaxed" pixels, counted);
//     - local --aa 4 (II and IV) against raytrace --spp 16:
//       |aa4 - ref| <= aa_coverage * range3(ref) + aa_tol at every pixel,
//       and the RMSE over the image <= aa_rms. aa_coverage defaults to
//       0.5/4 + 1/64: the trapezoid rule over 4 sub-scanlines misplaces at
//       most half a sub-scanline spacing of coverage (a horizontal edge),
//       bisection locates curved silhouettes to kBisectTolerance = 1/64 px;
//       aa_tol covers the reference's own sampling error and shading at
//       figure centroids. A pixel over that bound is held to the range
//       inside it instead: aa_coverage of it, or aa_traced (1/2) near
//       mirrors, glass and curved bodies, whose spans are sampled or
//       interpolated from pixel corners (docs/multiscan.md);
//  3. no speckles: a pixel that differs from each of its neighbours by more
//     than `speckle` (largest channel) where the reference's 3x3
//     neighbourhood is smooth (range below speckle / 2) and the scene is
//     smooth inside the pixel too (16 x 16 point samples, same range): a
//     thin feature that a pixel centre happens to hit is not a speckle;
//  4. no cracks: each mode is rendered twice, the second time with the
//     background raised by 1 in every channel, so the difference is the
//     weight with which the pixel sees the background (directly, or through
//     mirrors and glass). Where the reference sees no background anywhere
//     in the 3x3 neighbourhood (a closed surface), a mode may not see more
//     than 0.5 (point) or crack_aa (aa 4).
//
// Set LOCUS_STABILITY_DUMP=DIR to write every image as PNG, and
// LOCUS_STABILITY_VERBOSE=1 to print every pixel over its first bound.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "common/base/image.h"
#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scan/multiscan.h"
#include "common/scan/scanline.h"
#include "common/scene/polyhedron.h"
#include "common/trace/raytrace.h"
#include "tests/render_compare.h"

namespace locus {
namespace stability {

using testing_util::camera_scene;
using testing_util::distance_to_edge;
using testing_util::quad;

inline constexpr int kAa = 4;     // the multi-scanning mode under test
inline constexpr int kRefSpp = 16;  // the reference: raytrace spp 16 x 16

struct Bounds {
  // Point-sampled modes against configuration I: pixels excepted (edge or
  // shadow boundary) at most this many per mode.
  int point_exceptions = 0;
  // Configuration I against the spp 16 reference.
  double point_tol = 0.02;
  // Sub-pixel features: a pixel centre that hits one is an isolated pixel
  // where the reference is smooth. That is point sampling's aliasing, not a
  // speckle, so configuration I's speckle check is skipped (the other point
  // modes are still held to I pixel for pixel).
  bool point_aliasing = false;
  // aa 4 against the spp 16 reference.
  double aa_coverage = 0.5 / kAa + kBisectTolerance;
  double aa_tol = 0.02;
  double aa_rms = 0.01;
  // Ray-traced pixels (mirrors, glass, curved bodies) whose function has
  // detail finer than the 3x3 averages show (a reflection compressed at a
  // mirror's rim, the floor's edge seen through a slab at grazing angles):
  // the error is bounded by this fraction of the function's range inside
  // the pixel. Ray-traced pieces are interpolated from the pixel's corner
  // samples where those agree within kContrast = 0.05 (aa 4; kContrast / (N/4)
  // above), else sampled once,
  // or N/2 times across the piece where the corners see one material but
  // differ (pixel_samples.cpp): at aa 4, 1/4 of the range in x for one edge
  // and the trapezoid rule's 1/8 in y; a feature inside the pixel that no
  // corner sees may be lost where the corners agree. Was 1/4 with the
  // earlier four samples per refined piece (docs/multiscan.md).
  double aa_traced = 0.5;
  // Speckles and cracks.
  double speckle = 0.2;
  double crack_aa = 0.02;
};

struct ModeResult {
  std::string name;
  RenderParams params;
  Image img;     // the scene as given
  Image img_bg;  // background + 1
  // Measured.
  int nonfinite = 0;
  int mismatches = 0;  // point modes vs I, not excepted
  int edge_exceptions = 0, boundary_exceptions = 0;
  int speckles = 0, cracks = 0;
  int bound_violations = 0;  // against the spp 16 reference
  int relaxed = 0;           // pixels within bound only by their in-pixel range
  int max_diff8_i = 0;       // point modes: largest 8-bit difference from I
  double max_diff = 0;       // largest |mode - ref16| (linear)
  double worst_ratio = 0;    // largest |diff| / allowed
  double rms = 0;            // RMSE against the spp 16 reference
  int first_bad_x = -1, first_bad_y = -1;
  std::string first_bad;
};

struct CaseResult {
  std::vector<ModeResult> modes;  // I, RT, II, III, IV, II aa4, IV aa4, ref16
  const ModeResult& mode(const std::string& name) const {
    for (const ModeResult& m : modes) {
      if (m.name == name) return m;
    }
    ADD_FAILURE() << "no mode " << name;
    return modes.front();
  }
};

inline RenderParams params(Method m, Boxes b, int aa, int spp) {
  RenderParams p;
  p.method = m;
  p.boxes = b;
  p.aa = aa;
  p.spp = spp;
  p.threads = 2;
  return p;
}

inline Image render_or_fail(const Scene& s, const RenderParams& p, const std::string& what) {
  auto r = render_image(s, p);
  EXPECT_TRUE(r.ok()) << what << ": " << (r.ok() ? "" : r.status().message());
  if (!r.ok()) return Image(s.camera.width, s.camera.height);
  return std::move(r->pixels);
}

inline float chan_max_abs(const float* a, const float* b) {
  float d = 0;
  for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(a[c] - b[c]));
  return d;
}

// Largest channel range of `img` over the 3x3 neighbourhood of (x, y).
inline double range3(const Image& img, int x, int y) {
  double r = 0;
  for (int c = 0; c < 3; ++c) {
    float lo = 1e30f, hi = -1e30f;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= img.width || yy >= img.height) continue;
        lo = std::min(lo, img.pixel(xx, yy)[c]);
        hi = std::max(hi, img.pixel(xx, yy)[c]);
      }
    }
    r = std::max(r, static_cast<double>(hi - lo));
  }
  return r;
}

// Background weight seen at (x, y): mean over channels of (bg+1) - bg.
inline double bg_weight(const Image& img, const Image& img_bg, int x, int y) {
  const float* a = img.pixel(x, y);
  const float* b = img_bg.pixel(x, y);
  return ((b[0] - a[0]) + (b[1] - a[1]) + (b[2] - a[2])) / 3.0;
}

inline bool verbose() { return std::getenv("LOCUS_STABILITY_VERBOSE") != nullptr; }

inline int count_nonfinite(const Image& img) {
  int n = 0;
  for (float v : img.rgb) n += !std::isfinite(v);
  return n;
}

// Largest channel range of the point-sampled image over pixel (x, y):
// 16 x 16 samples at the centres of its strata.
inline double range_in_pixel(const PreparedScene& ps, int x, int y) {
  Color lo(1e30), hi(-1e30);
  const int n = 16;
  for (int b = 0; b < n; ++b) {
    for (int a = 0; a < n; ++a) {
      const Color c = testing_util::trace_at(ps, x + (a + 0.5) / n, y + (b + 0.5) / n);
      lo = glm::min(lo, c);
      hi = glm::max(hi, c);
    }
  }
  return max_component(hi - lo);
}

// Pixels differing from each neighbour by more than `t` where `ref` is
// smooth, and the scene itself is smooth inside the pixel (`in_pixel`: the
// range of the function over it). A thin feature that a pixel centre hits
// (an edge of a refracted image 0.1 px wide) is detail, not a speckle.
template <class InPixel>
inline int count_speckles(const Image& img, const Image& ref, double t, InPixel&& in_pixel,
                          int* bx = nullptr, int* by = nullptr) {
  int n = 0;
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      bool isolated = true;
      for (int dy = -1; dy <= 1 && isolated; ++dy) {
        for (int dx = -1; dx <= 1 && isolated; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= img.width || yy >= img.height) {
            continue;
          }
          if (chan_max_abs(img.pixel(x, y), img.pixel(xx, yy)) <= t) isolated = false;
        }
      }
      if (isolated && range3(ref, x, y) < t / 2 && in_pixel(x, y) < t / 2) {
        if (n == 0 && bx) *bx = x, *by = y;
        if (verbose()) {
          std::printf("  speckle at %d,%d: ", x, y);
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = std::clamp(x + dx, 0, img.width - 1), yy = std::clamp(y + dy, 0, img.height - 1);
              std::printf("(%.3f %.3f %.3f | ref %.3f %.3f %.3f) ", img.pixel(xx, yy)[0], img.pixel(xx, yy)[1],
                          img.pixel(xx, yy)[2], ref.pixel(xx, yy)[0], ref.pixel(xx, yy)[1], ref.pixel(xx, yy)[2]);
            }
            std::printf("\n    ");
          }
          std::printf("\n");
        }
        ++n;
      }
    }
  }
  return n;
}

// Pixels seeing more than `tau` background where the reference sees none in
// the 3x3 neighbourhood.
inline int count_cracks(const ModeResult& m, const ModeResult& ref, double tau, int* bx = nullptr,
                        int* by = nullptr) {
  int n = 0;
  const int w = m.img.width, h = m.img.height;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      bool closed = true;
      for (int dy = -1; dy <= 1 && closed; ++dy) {
        for (int dx = -1; dx <= 1 && closed; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          if (std::abs(bg_weight(ref.img, ref.img_bg, xx, yy)) > 1e-6) closed = false;
        }
      }
      if (closed && bg_weight(m.img, m.img_bg, x, y) > tau) {
        if (n == 0 && bx) *bx = x, *by = y;
        ++n;
      }
    }
  }
  return n;
}

// Pixels the local method may ray trace (multiscan.h): those a curved
// body's bounding polyhedron, a mirror or glass face comes within a pixel
// of; all of them when the eye is inside a bounding polyhedron.
inline std::vector<char> traced_pixels(const PreparedScene& ps) {
  const int w = ps.camera.width, h = ps.camera.height;
  std::vector<char> t(static_cast<size_t>(w) * h, ps.scan->trace_everything ? 1 : 0);
  for (const ScanFace& f : ps.scan->faces) {
    const Material& m = ps.scene.materials[ps.scene.objects[ps.prims.prims[f.prim].object].material];
    if (!f.curved && !(m.ks > 0 || m.t > 0)) continue;
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const Vec2& p : f.outline) {
      x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
    }
    const int i0 = std::max(0, static_cast<int>(std::floor(x0)) - 1);
    const int i1 = std::min(w - 1, static_cast<int>(std::floor(x1)) + 1);
    const int j0 = std::max(0, static_cast<int>(std::floor(y0)) - 1);
    const int j1 = std::min(h - 1, static_cast<int>(std::floor(y1)) + 1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) t[static_cast<size_t>(j) * w + i] = 1;
    }
  }
  return t;
}

inline bool dump_enabled() { return std::getenv("LOCUS_STABILITY_DUMP") != nullptr; }

inline void dump(const std::string& name, const std::string& mode, const Image& img) {
  if (!dump_enabled()) return;
  std::string file = std::string(std::getenv("LOCUS_STABILITY_DUMP")) + "/" + name + "_" + mode + ".png";
  for (char& c : file) {
    if (c == ' ') c = '_';
  }
  (void)write_image(file, img);
}

// Every mode, the reference last: configuration I first (the point
// reference), the other point-sampled modes, multi-scanning, raytrace spp 16.
inline std::vector<std::pair<std::string, RenderParams>> all_modes() {
  return {
      {"I", params(Method::kRaytrace, Boxes::kNone, 0, 1)},
      {"RT", params(Method::kRaytrace, Boxes::kEyeShadow, 0, 1)},
      {"II", params(Method::kLocal, Boxes::kNone, 0, 1)},
      {"III", params(Method::kLocal, Boxes::kEye, 0, 1)},
      {"IV", params(Method::kLocal, Boxes::kEyeShadow, 0, 1)},
      {"II-aa4", params(Method::kLocal, Boxes::kNone, kAa, 1)},
      {"IV-aa4", params(Method::kLocal, Boxes::kEyeShadow, kAa, 1)},
      {"ref16", params(Method::kRaytrace, Boxes::kEyeShadow, 0, kRefSpp)},
  };
}

// Image coordinates (x right, y down, pixels) of world point p.
inline Vec2 project(const Scene& s, const Vec3& p) {
  const CameraFrame cam(s.camera);
  const Vec3 d = p - cam.from;
  const double z = glm::dot(d, cam.w);
  return Vec2((glm::dot(d, cam.u) / z / (cam.tan_half * cam.aspect) + 1) * 0.5 * cam.width,
              (1 - glm::dot(d, cam.v) / z / cam.tan_half) * 0.5 * cam.height);
}

// Renders `s` in every mode and checks it (see the top of this file). The
// failures are reported with their pixel, and every number is printed.
inline CaseResult check_case(const Scene& s, const Bounds& b, const std::string& name) {
  CaseResult cr;
  Scene s_bg = s;
  s_bg.background = s.background + Color(1.0);
  for (const auto& [mname, p] : all_modes()) {
    ModeResult m;
    m.name = mname;
    m.params = p;
    m.img = render_or_fail(s, p, name + " " + mname);
    m.img_bg = render_or_fail(s_bg, p, name + " " + mname + " (background + 1)");
    m.nonfinite = count_nonfinite(m.img) + count_nonfinite(m.img_bg);
    dump(name, mname, m.img);
    cr.modes.push_back(std::move(m));
  }
  const ModeResult& ref1 = cr.modes[0];
  const ModeResult& ref16 = cr.modes.back();
  const int w = s.camera.width, h = s.camera.height;

  // For the exceptions of point modes: configuration I's tracer and the
  // scanline pass's projected edges.
  auto ps_i = prepare_scene(s, ref1.params);
  auto ps_scan = prepare_scene(s, cr.modes[2].params);
  EXPECT_TRUE(ps_i.ok() && ps_scan.ok()) << name;
  if (!ps_i.ok() || !ps_scan.ok()) return cr;
  const std::vector<char> traced = traced_pixels(**ps_scan);

  for (ModeResult& m : cr.modes) {
    const bool is_ref = &m == &ref16;
    const bool point = m.params.aa == 0 && m.params.spp == 1;
    if (point && &m != &ref1) {
      // Against configuration I, 8-bit.
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const float* lp = m.img.pixel(x, y);
          const int diff = testing_util::max_diff8(ref1.img.pixel(x, y), lp);
          m.max_diff8_i = std::max(m.max_diff8_i, diff);
          if (diff <= 2) continue;
          // Either side of an edge is right, so the value must be one the
          // ray tracer gives 1e-6 px away from the centre (in one of 8
          // directions): not something behind both sides (a crack).
          bool beside = false;
          for (int k = 0; k < 8 && !beside; ++k) {
            const double ang = k * 0.25 * M_PI;
            const Color c = testing_util::trace_at(**ps_i, x + 0.5 + 1e-6 * std::cos(ang),
                                                   y + 0.5 + 1e-6 * std::sin(ang));
            const float v[3] = {static_cast<float>(c.x), static_cast<float>(c.y),
                                static_cast<float>(c.z)};
            beside = testing_util::max_diff8(v, lp) <= 2;
          }
          if (beside) {
            if (distance_to_edge(*(*ps_scan)->scan, x + 0.5, y + 0.5) < 1e-6) {
              ++m.edge_exceptions;
            } else {
              ++m.boundary_exceptions;
            }
            continue;
          }
          if (m.mismatches++ == 0) {
            m.first_bad_x = x;
            m.first_bad_y = y;
            char buf[200];
            std::snprintf(buf, sizeof buf, "pixel %d,%d: %s (%.4f %.4f %.4f) vs I (%.4f %.4f %.4f)",
                          x, y, m.name.c_str(), lp[0], lp[1], lp[2], ref1.img.pixel(x, y)[0],
                          ref1.img.pixel(x, y)[1], ref1.img.pixel(x, y)[2]);
            m.first_bad = buf;
          }
        }
      }
    }
    if (!is_ref && (!point || &m == &ref1)) {
      // Against the spp 16 reference.
      double s2 = 0;
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const float* a = m.img.pixel(x, y);
          const float* r = ref16.img.pixel(x, y);
          const double d = chan_max_abs(a, r);
          for (int c = 0; c < 3; ++c) s2 += (a[c] - r[c]) * static_cast<double>(a[c] - r[c]);
          m.max_diff = std::max(m.max_diff, d);
          const double r3 = range3(ref16.img, x, y);
          double allowed = point ? r3 + b.point_tol : b.aa_coverage * r3 + b.aa_tol;
          if (d > allowed) {
            // The 3x3 averages hide detail finer than a pixel (a reflection
            // compressed at a mirror's rim): measure the range inside it.
            const double rp = range_in_pixel(**ps_i, x, y);
            const double k = point ? 1.0 : traced[y * w + x] ? b.aa_traced : b.aa_coverage;
            const double relaxed = std::max(allowed, k * rp + (point ? b.point_tol : b.aa_tol));
            if (d <= relaxed) ++m.relaxed;
            if (verbose()) {
              std::printf("  %s pixel %d,%d: diff %.4f, range3 %.4f, in pixel %.4f, traced %d, allowed %.4f\n",
                          m.name.c_str(), x, y, d, r3, rp, int(traced[y * w + x]), relaxed);
            }
            allowed = relaxed;
          }
          m.worst_ratio = std::max(m.worst_ratio, d / allowed);
          if (d > allowed && m.bound_violations++ == 0) {
            char buf[240];
            std::snprintf(buf, sizeof buf,
                          "pixel %d,%d: %s (%.4f %.4f %.4f) vs ref16 (%.4f %.4f %.4f), allowed %.4f",
                          x, y, m.name.c_str(), a[0], a[1], a[2], r[0], r[1], r[2], allowed);
            if (m.first_bad.empty()) m.first_bad = buf;
          }
        }
      }
      m.rms = std::sqrt(s2 / (3.0 * w * h));
    }
    // Speckles: point modes against I's smoothness (I itself against the
    // reference's, unless sub-pixel features alias), aa against ref16.
    int sx = -1, sy = -1;
    if (!is_ref) {
      const Image& smooth_ref = (point && &m != &ref1) ? ref1.img : ref16.img;
      if (!(point && &m == &ref1 && b.point_aliasing)) {
        m.speckles = count_speckles(
            m.img, smooth_ref, b.speckle, [&](int x, int y) { return range_in_pixel(**ps_i, x, y); },
            &sx, &sy);
      }
      const ModeResult& crack_ref = point ? ref1 : ref16;
      if (&m != &crack_ref) m.cracks = count_cracks(m, crack_ref, point ? 0.5 : b.crack_aa, &sx, &sy);
      if (&m == &ref1) m.cracks = count_cracks(m, ref16, 0.5, &sx, &sy);
    }

    const bool vs_i = point && &m != &ref1, vs_ref = !is_ref && !vs_i;
    std::printf("[%s] %-7s nonfinite %d", name.c_str(), m.name.c_str(), m.nonfinite);
    if (vs_i) {
      std::printf(" | vs I: max %d/255, mismatch %d, edge exc %d, boundary exc %d", m.max_diff8_i,
                  m.mismatches, m.edge_exceptions, m.boundary_exceptions);
    }
    if (vs_ref) {
      std::printf(" | vs ref16: max %.4f, rms %.4f, worst/allowed %.3f, over %d, relaxed %d",
                  m.max_diff, m.rms, m.worst_ratio, m.bound_violations, m.relaxed);
    }
    std::printf(" | speckles %d, cracks %d\n", m.speckles, m.cracks);
    EXPECT_EQ(m.nonfinite, 0) << name << " " << m.name << ": NaN or Inf";
    EXPECT_EQ(m.mismatches, 0) << name << " " << m.name << " disagrees with configuration I at "
                               << m.mismatches << " pixels; first " << m.first_bad;
    EXPECT_LE(m.edge_exceptions + m.boundary_exceptions, b.point_exceptions)
        << name << " " << m.name << ": excepted pixels";
    EXPECT_EQ(m.bound_violations, 0) << name << " " << m.name << " exceeds its bound against "
                                     << "raytrace spp 16 at " << m.bound_violations
                                     << " pixels; first " << m.first_bad;
    if (!point && !is_ref) {
      EXPECT_LE(m.rms, b.aa_rms) << name << " " << m.name << " RMSE";
    }
    EXPECT_EQ(m.speckles, 0) << name << " " << m.name << ": speckles, first at " << sx << "," << sy;
    EXPECT_EQ(m.cracks, 0) << name << " " << m.name << ": cracks, first at " << sx << "," << sy;
  }
  return cr;
}

// Renders scenes a and b in every mode and returns, per mode, the largest
// channel difference between them over the 3x3 neighbourhoods of `pixels`
// (all pixels if empty), printing it.
inline double max_change(const Scene& a, const Scene& b, const std::vector<Vec2>& pixels,
                         const std::string& what) {
  double worst = 0;
  for (const auto& [mname, p] : all_modes()) {
    const Image ia = render_or_fail(a, p, what), ib = render_or_fail(b, p, what);
    double d = 0;
    for (int y = 0; y < ia.height; ++y) {
      for (int x = 0; x < ia.width; ++x) {
        bool near = pixels.empty();
        for (const Vec2& q : pixels) near = near || (std::abs(x + 0.5 - q.x) < 1.6 && std::abs(y + 0.5 - q.y) < 1.6);
        if (near) d = std::max(d, static_cast<double>(chan_max_abs(ia.pixel(x, y), ib.pixel(x, y))));
      }
    }
    std::printf("[%s] %-7s largest change %.3g\n", what.c_str(), mname.c_str(), d);
    worst = std::max(worst, d);
  }
  return worst;
}

// Materials.
inline Material diffuse(const Color& c) {
  Material m;
  m.color = c;
  return m;
}
inline Material mirror(double ks = 0.8, const Color& c = Color(0.8)) {
  Material m;
  m.color = c;
  m.kd = 0.2;
  m.ks = ks;
  m.shine = 30;
  return m;
}
inline Material glass(double ior = 1.5, double t = 0.9) {
  Material m;
  m.color = Color(1.0);
  m.kd = 0.05;
  m.ks = 0.1;
  m.shine = 60;
  m.t = t;
  m.ior = ior;
  return m;
}

inline Object object(Shape shape, int material) {
  Object o;
  o.shape = std::move(shape);
  o.material = material;
  return o;
}
inline Object sphere(const Vec3& c, double r, int material) { return object(Sphere{c, r}, material); }
inline Object box(const Vec3& lo, const Vec3& hi, int material) {
  return object(make_box(lo, hi), material);
}
// A square floor y = height, front side up.
inline Object floor_quad(double half, int material, double height = 0) {
  return quad(Vec3(-half, height, half), Vec3(half, height, half), Vec3(half, height, -half),
              Vec3(-half, height, -half), material);
}

}  // namespace stability
}  // namespace locus
