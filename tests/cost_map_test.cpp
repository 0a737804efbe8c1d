// The cost map (issue #27 item 5; docs/cost-map.md): the per-pixel counts
// sum to the render's Stats, collecting them changes no pixel, and the
// ray-traced region agrees with an independent mask of what the local method
// ray traces (METHOD.md §4: spans of mirrors and glass, and of curved
// bodies' bounding polyhedra).
#include "common/base/cost_map.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "common/prepare/bounding.h"
#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "common/trace/raytrace.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

Scene paper_scene(const std::string& name) {
  auto s = load_scene(std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/" + name);
  EXPECT_TRUE(s.ok()) << s.status().message();
  return s.ok() ? *s : Scene{};
}

// Scenes (d) (mirror spheres) and (a) (glass), at w x h.
std::vector<std::pair<std::string, Scene>> mirror_and_glass(int w, int h) {
  std::vector<std::pair<std::string, Scene>> scenes = {{"d", paper_scene("d_spheres_2lights.json")},
                                                       {"a", paper_scene("a_glass.json")}};
  for (auto& [name, s] : scenes) {
    s.camera.width = w;
    s.camera.height = h;
  }
  return scenes;
}

RenderParams local_params(int aa) { return testing_util::config_iv_params(aa, 2); }

RenderParams raytrace_params() {
  RenderParams p;
  p.method = Method::kRaytrace;
  p.boxes = Boxes::kEyeShadow;
  p.threads = 2;
  return p;
}

struct Rendered {
  BandResult result;
  CostBuffer cost;
};

Rendered render_with_cost(const Scene& s, const RenderParams& p) {
  Rendered r;
  auto res = render_image(s, p, &r.cost);
  EXPECT_TRUE(res.ok()) << res.status().message();
  if (res.ok()) r.result = std::move(*res);
  return r;
}

bool is_curved(const PrimRef& ref) {
  return ref.kind == PrimKind::kSphere || ref.kind == PrimKind::kCone || ref.kind == PrimKind::kCsg;
}

bool reflects_or_refracts(const Scene& s, int object) {
  const Material& m = s.materials[s.objects[object].material];
  return m.ks > 0 || m.t > 0;
}

// A convex polyhedron as planes n . x <= d (n outward).
struct Planes {
  std::vector<Vec3> n;
  std::vector<double> d;
};

Planes planes_of(const Polyhedron& poly) {
  Planes p;
  for (const auto& face : poly.faces) {
    // Newell's normal of the face (counter-clockwise seen from outside).
    Vec3 n(0.0);
    for (size_t k = 0; k < face.size(); ++k) {
      const Vec3& a = poly.vertices[face[k]];
      const Vec3& b = poly.vertices[face[(k + 1) % face.size()]];
      n += Vec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    n = glm::normalize(n);
    p.n.push_back(n);
    p.d.push_back(glm::dot(n, poly.vertices[face[0]]));
  }
  return p;
}

// Where the ray enters the polyhedron at t >= tmin (Cyrus-Beck clipping);
// kInf if it does not meet it.
double entry(const Planes& p, const Ray& ray, double tmin) {
  double t0 = tmin, t1 = kInf;
  for (size_t k = 0; k < p.n.size(); ++k) {
    const double den = glm::dot(p.n[k], ray.dir);
    const double num = p.d[k] - glm::dot(p.n[k], ray.origin);
    if (den == 0) {
      if (num < 0) return kInf;
    } else if (den < 0) {
      t0 = std::max(t0, num / den);
    } else {
      t1 = std::min(t1, num / den);
    }
  }
  return t0 <= t1 ? t0 : kInf;
}

// The independent masks, from rays at the pixel centres (what --method
// raytrace --spp 1 casts), with the ray tracer's first hit:
//  - `first_hit`: the first surface hit is a mirror, glass or curved body;
//  - `method`: what the local method ray traces (METHOD.md §4): along the
//    ray, the nearest of the flat surfaces and of the curved bodies'
//    bounding polyhedra (as the scanline pass sees them) is a bounding
//    polyhedron, or a mirror's or glass's surface.
struct Masks {
  int width = 0, height = 0;
  std::vector<char> first_hit, method;
};

Masks independent_masks(const Scene& scene) {
  auto prepared = prepare_scene(scene, raytrace_params());
  EXPECT_TRUE(prepared.ok());
  const PreparedScene& ps = **prepared;
  Stats stats;
  Tracer tracer(ps, stats);
  std::vector<int> flat;
  std::vector<Planes> polyhedra;
  for (int i = 0; i < static_cast<int>(ps.prims.prims.size()); ++i) {
    const PrimRef& ref = ps.prims.prims[i];
    if (!is_curved(ref)) {
      flat.push_back(i);
      continue;
    }
    for (const Polyhedron& poly : bounding_polyhedra(ps.scene, ref.object))
      polyhedra.push_back(planes_of(poly));
  }
  const CameraFrame& cam = ps.camera;
  Masks m;
  m.width = cam.width;
  m.height = cam.height;
  m.first_hit.assign(static_cast<size_t>(cam.width) * cam.height, 0);
  m.method = m.first_hit;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Ray ray{cam.from, cam.direction(x + 0.5, y + 0.5)};
      const size_t i = static_cast<size_t>(y) * cam.width + x;
      if (const auto hit = tracer.nearest(ray, cam.hither, kInf)) {
        const PrimRef& ref = ps.prims.prims[hit->prim];
        m.first_hit[i] = is_curved(ref) || reflects_or_refracts(ps.scene, ref.object);
      }
      double poly_t = kInf;
      for (const Planes& p : polyhedra) poly_t = std::min(poly_t, entry(p, ray, cam.hither));
      const auto flat_hit = tracer.nearest_among(ray, cam.hither, kInf, flat);
      const double flat_t = flat_hit ? flat_hit->t : kInf;
      m.method[i] =
          poly_t < flat_t ||
          (flat_hit && reflects_or_refracts(ps.scene, ps.prims.prims[flat_hit->prim].object));
    }
  }
  return m;
}

// Pixels where `region` and `mask` differ, other than within one pixel of
// the mask's outline (a pixel whose 3 x 3 neighbourhood holds both values).
int differences_off_outline(const Masks& m, const std::vector<char>& mask,
                            const std::function<bool(int, int)>& region) {
  int bad = 0;
  for (int y = 0; y < m.height; ++y) {
    for (int x = 0; x < m.width; ++x) {
      const bool v = mask[static_cast<size_t>(y) * m.width + x];
      if (region(x, y) == v) continue;
      bool outline = false;
      for (int dy = -1; dy <= 1 && !outline; ++dy) {
        for (int dx = -1; dx <= 1 && !outline; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= m.width || yy >= m.height) continue;
          outline = mask[static_cast<size_t>(yy) * m.width + xx] != v;
        }
      }
      if (!outline) ++bad;
    }
  }
  return bad;
}

// The acceptance test of issue #27 item 5 on scene (d), at the CLI's
// default settings (local, eye+shadow, --aa 4) and at point sampling.
TEST(CostMap, RayTracedRegionMatchesIndependentMask) {
  const Scene scene = paper_scene("d_spheres_2lights.json");
  const Masks masks = independent_masks(scene);
  const size_t n = masks.method.size();
  const size_t in_mask = std::count(masks.method.begin(), masks.method.end(), 1);
  const size_t in_first_hit = std::count(masks.first_hit.begin(), masks.first_hit.end(), 1);
  // Non-trivial: the four mirror spheres' polyhedra, well inside the image.
  EXPECT_GT(in_mask, n / 20);
  EXPECT_LT(in_mask, n / 2);
  EXPECT_GT(in_first_hit, n / 20);
  for (const int aa : {4, 0}) {
    const Rendered r = render_with_cost(scene, local_params(aa));
    auto region = [&](int x, int y) { return r.cost.at(x, y).traced_span; };
    size_t traced = 0;
    for (const PixelCost& p : r.cost.pixels) traced += p.traced_span;
    EXPECT_EQ(differences_off_outline(masks, masks.method, region), 0) << "aa " << aa;
    // Every pixel whose first hit is a mirror or a curved body is traced
    // (but for its outline); the rest of the region is the polyhedra's
    // margin around the spheres' outlines.
    auto traced_where_first_hit = [&](int x, int y) {
      return masks.first_hit[static_cast<size_t>(y) * masks.width + x] && region(x, y);
    };
    EXPECT_EQ(differences_off_outline(masks, masks.first_hit, traced_where_first_hit), 0)
        << "aa " << aa;
    std::printf(
        "aa %d: traced %zu pixels, method's mask %zu, first hit on a mirror or curved "
        "body %zu\n",
        aa, traced, in_mask, in_first_hit);
  }
}

void expect_counts_sum_to_stats(const Rendered& r, const std::string& what) {
  const Stats sum = r.cost.totals();
  const Stats& s = r.result.stats;
  EXPECT_EQ(sum.rays_eye, s.rays_eye) << what;
  EXPECT_EQ(sum.rays_reflected, s.rays_reflected) << what;
  EXPECT_EQ(sum.rays_refracted, s.rays_refracted) << what;
  EXPECT_EQ(sum.rays_shadow, s.rays_shadow) << what;
  EXPECT_EQ(sum.tests_shadow_volume, s.tests_shadow_volume) << what;
  EXPECT_EQ(sum.pixels_ray_traced, s.pixels_ray_traced) << what;
}

TEST(CostMap, CountsSumToStats) {
  const auto scenes = mirror_and_glass(160, 120);
  RenderParams no_boxes = local_params(0);
  no_boxes.boxes = Boxes::kNone;  // configuration II: shadow rays at secondary points
  for (const auto& [name, s] : scenes) {
    expect_counts_sum_to_stats(render_with_cost(s, local_params(4)), name + " aa 4");
    expect_counts_sum_to_stats(render_with_cost(s, local_params(0)), name + " aa 0");
    expect_counts_sum_to_stats(render_with_cost(s, no_boxes), name + " II");
    expect_counts_sum_to_stats(render_with_cost(s, raytrace_params()), name + " raytrace");
  }
  // The glass scene refracts and tests volumes: the counts are not all zero.
  const Rendered r = render_with_cost(scenes[1].second, local_params(4));
  EXPECT_GT(r.result.stats.rays_refracted, 0u);
  EXPECT_GT(r.result.stats.tests_shadow_volume, 0u);
}

TEST(CostMap, NoRayTracedRegionWithoutMirrorsGlassOrCurvedBodies) {
  Scene s = paper_scene("d_spheres_2lights.json");
  s.camera.width = 160;
  s.camera.height = 120;
  // The prisms and the floor alone, all diffuse.
  std::vector<Object> kept;
  for (const Object& o : s.objects) {
    if (!std::holds_alternative<Sphere>(o.shape) && !std::holds_alternative<Cone>(o.shape))
      kept.push_back(o);
  }
  ASSERT_LT(kept.size(), s.objects.size());
  s.objects = kept;
  for (Material& m : s.materials) m.ks = m.t = 0;
  for (const int aa : {0, 4}) {
    const Rendered r = render_with_cost(s, local_params(aa));
    size_t traced = 0, worked = 0, grazed = 0;
    for (const PixelCost& p : r.cost.pixels) {
      traced += p.traced_span;
      grazed += p.traced;
      worked += p.work() > 0;
    }
    EXPECT_EQ(traced, 0u) << "aa " << aa;
    // Eye rays where a pixel's sample missed its face (an edge grazed) are
    // counted, but they are no ray-traced span.
    std::printf("aa %d: %zu pixels with an eye ray at a grazed edge\n", aa, grazed);
    EXPECT_GT(worked, 0u) << "aa " << aa;  // the shadow-volume tests are there
    // ... and the picture has no outline colour.
    const Image img = cost_map_image(r.cost);
    int cyan = 0;
    for (int y = 0; y < img.height; ++y) {
      for (int x = 0; x < img.width; ++x) {
        const float* p = img.pixel(x, y);
        cyan += p[0] == 0.0f && p[1] == 1.0f && p[2] == 1.0f;
      }
    }
    // Only the legend's swatch (5 x 5 font pixels at this width).
    EXPECT_EQ(cyan, 25) << "aa " << aa;
  }
}

TEST(CostMap, CollectingChangesNoPixel) {
  for (const auto& [name, s] : mirror_and_glass(128, 96)) {
    for (const RenderParams& p : {local_params(4), local_params(0), raytrace_params()}) {
      auto plain = render_image(s, p);
      ASSERT_TRUE(plain.ok());
      const Rendered r = render_with_cost(s, p);
      ASSERT_EQ(plain->pixels.rgb.size(), r.result.pixels.rgb.size());
      EXPECT_EQ(std::memcmp(plain->pixels.rgb.data(), r.result.pixels.rgb.data(),
                            plain->pixels.rgb.size() * sizeof(float)),
                0)
          << name << " method " << static_cast<int>(p.method) << " aa " << p.aa;
      EXPECT_EQ(plain->stats.rays_eye, r.result.stats.rays_eye);
    }
  }
}

// A band's buffer holds the band's rows, and its pixels' counts are those
// of the same rows of the whole image (each row's work is its own, but for
// multi-scanning's chunks; point sampling here).
TEST(CostMap, BandBufferHoldsItsRows) {
  Scene s = paper_scene("d_spheres_2lights.json");
  s.camera.width = 96;
  s.camera.height = 64;
  const RenderParams p = local_params(0);
  auto prepared = prepare_scene(s, p);
  ASSERT_TRUE(prepared.ok());
  CostBuffer whole, band;
  render_band(**prepared, Band{0, 64}, p, nullptr, &whole);
  render_band(**prepared, Band{20, 40}, p, nullptr, &band);
  EXPECT_EQ(band.y0, 20);
  EXPECT_EQ(band.y1, 40);
  ASSERT_EQ(band.pixels.size(), 96u * 20);
  for (int y = 20; y < 40; ++y) {
    for (int x = 0; x < 96; ++x) {
      EXPECT_EQ(band.at(x, y).work(), whole.at(x, y).work()) << x << "," << y;
      EXPECT_EQ(band.at(x, y).traced_span, whole.at(x, y).traced_span) << x << "," << y;
    }
  }
}

TEST(CostMap, PictureScaleOutlineAndLegend) {
  // The ramp's lightness rises (Rec. 709 luma of its display values).
  double last = -1;
  for (int k = 0; k <= 100; ++k) {
    const Color c = cost_ramp(k / 100.0);
    const double luma = 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
    EXPECT_GT(luma, last) << k;
    last = luma;
  }
  EXPECT_EQ(cost_scale_top(0), 1u);
  EXPECT_EQ(cost_scale_top(1), 1u);
  EXPECT_EQ(cost_scale_top(3), 5u);
  EXPECT_EQ(cost_scale_top(150), 200u);
  EXPECT_EQ(cost_scale_top(1000), 1000u);
  // A traced square of work 10 in a field of 0: cyan on its border only, the
  // ramp's top inside (10 is the scale's top), its bottom outside.
  CostBuffer b;
  b.reset(200, 0, 200);
  for (int y = 50; y < 80; ++y) {
    for (int x = 50; x < 80; ++x) {
      b.at(x, y).rays_eye = 10;
      b.at(x, y).traced = b.at(x, y).traced_span = true;
    }
  }
  const Image img = cost_map_image(b);
  ASSERT_EQ(img.width, 200);
  ASSERT_EQ(img.height, 200);
  auto is = [&](int x, int y, const Color& c) {
    const float* p = img.pixel(x, y);
    return p[0] == static_cast<float>(c.x) && p[1] == static_cast<float>(c.y) &&
           p[2] == static_cast<float>(c.z);
  };
  EXPECT_TRUE(is(50, 60, kTracedOutline));
  EXPECT_TRUE(is(79, 60, kTracedOutline));
  EXPECT_TRUE(is(60, 50, kTracedOutline));
  EXPECT_TRUE(is(60, 60, cost_ramp(1.0)));
  EXPECT_TRUE(is(10, 10, cost_ramp(0.0)));
  // The legend's strip covers the bottom rows; its text is drawn.
  EXPECT_FALSE(is(100, 199, cost_ramp(0.0)));
  Image text(40, 10);
  draw_cost_text(text, 0, 0, 1, "10", Color(1.0));
  int lit = 0;
  for (const float v : text.rgb) lit += v > 0;
  EXPECT_EQ(lit, 3 * (8 + 12));  // '1' has 8 pixels, '0' 12, 3 channels each
  EXPECT_EQ(cost_text_width("10", 1), 7);
}

}  // namespace
}  // namespace locus
