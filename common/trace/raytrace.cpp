#include "common/trace/raytrace.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/geometry/optics.h"
#include "common/prepare/hidden_faces.h"
#include "common/prepare/shadow_volume.h"
#include "common/trace/shadow_search.h"

namespace locus {
namespace {

// SHADING.md "Ray tree".
constexpr int kMaxDepth = 5;
constexpr double kMinWeight = 1.0 / 512.0;

Color beer(const Color& q, double d) {
  return Color(std::exp(-q.x * d), std::exp(-q.y * d), std::exp(-q.z * d));
}

// std::nextafter(x, +inf), inline for the positive finite values a ray's
// search bound takes (a library call per primitive test otherwise).
double next_up(double x) {
  if (x > 0 && x < kInf) return std::bit_cast<double>(std::bit_cast<uint64_t>(x) + 1);
  if (x == kInf) return x;  // no crossing yet: the bound stays infinite
  return std::nextafter(x, kInf);
}

}  // namespace

template <class Visit>
std::optional<SurfaceHit> Tracer::nearest_by(const Ray& ray, double tmin, double tmax,
                                             Visit&& visit) {
  // Crossings within kTieRel of the nearest distance are coincident surfaces
  // (doubled faces, an edge shared by two triangles). Among them the
  // primitive defined first in the scene wins. Candidates in the band of the
  // nearest distance seen so far are kept, so the choice is the same for
  // any traversal order (bit-identical images with and without boxes).
  thread_local std::vector<SurfaceHit> band;
  band.clear();
  double nearest_t = tmax;
  // A ray from the eye point skips the faces closed solids turn away from
  // it (hidden_faces.h): they are never its nearest crossing.
  const uint8_t cull = ray.origin == ps_.camera.from ? kCullEye : 0;
  // `slot`: the primitive's place in the hierarchy's leaf order, where the
  // walk gives it; a primitive copied there is tested from leaf_prims.
  // Always inlined: GCC called it from the AVX2 walk, whose lanes (the ray's
  // origin, reciprocals and bounds in eight registers) were then saved and
  // reloaded around every test (callgrind, def teapot at 256²: 7% of the
  // walk's instructions).
  // A culled primitive is known from PreparedScene::culls, a byte a
  // primitive, without reading its leaf copy (cache lines of their own).
  auto test = [&](int prim, int slot = -1) __attribute__((always_inline)) {
    if (!(cull && (ps_.culls[prim] & cull))) {
      const LeafPrim* lp = ps_.leaf_prim_at(slot);
      ++stats_.tests_ray_object;
      const double bound = std::min(tmax, nearest_t * (1.0 + kTieRel));
      if (lp) {
        Crossing c;
        if (leaf_nearest(*lp, ray, tmin, bound, &c)) {
          band.push_back(SurfaceHit{c.t, prim, c});
          if (c.t < nearest_t) nearest_t = c.t;
        }
      } else if (const auto c = intersect_nearest(ps_.prims, prim, ray, tmin, bound)) {
        band.push_back(SurfaceHit{c->t, prim, *c});
        if (c->t < nearest_t) nearest_t = c->t;
      }
    }
    return std::min(tmax, next_up(nearest_t * (1.0 + kTieRel)));
  };
  visit(test);
  const SurfaceHit* best = nullptr;
  const double limit = nearest_t * (1.0 + kTieRel);
  for (const SurfaceHit& h : band) {
    if (h.t <= limit && (!best || h.prim < best->prim)) best = &h;
  }
  if (!best) return std::nullopt;
  return *best;
}

std::optional<SurfaceHit> Tracer::nearest(const Ray& ray, double tmin, double tmax) {
  return nearest_by(ray, tmin, tmax, [&](auto& test) {
    if (ps_.bvh_for_rays) {
      traverse_bvh(ps_.bvh, ray, tmin, tmax, test);
    } else {
      for (int i = 0; i < static_cast<int>(ps_.prims.prims.size()); ++i) test(i);
    }
  });
}

std::optional<SurfaceHit> Tracer::nearest_among(const Ray& ray, double tmin, double tmax,
                                                const std::vector<int>& prims) {
  if (prims.size() < 2) {
    return nearest_by(ray, tmin, tmax, [&](auto& test) {
      for (const int p : prims) test(p, ps_.leaf_slot_of(p));
    });
  }
  // Nearest box first (the slab test's entry distance), and none whose box
  // the ray enters beyond the nearest crossing found: a primitive's
  // crossings lie inside its box. The choice among coincident crossings
  // does not depend on the order (nearest_by).
  thread_local std::vector<std::pair<double, int>> order;
  order.clear();
  const RayInv ri(ray);
  for (const int p : prims) order.emplace_back(box_entry(ps_.prims.bounds[p], ri, tmin), p);
  if (order.size() <= 16) {
    // Insertion: the lists are mostly a few primitives long.
    for (size_t i = 1; i < order.size(); ++i) {
      const std::pair<double, int> e = order[i];
      size_t k = i;
      for (; k > 0 && e < order[k - 1]; --k) order[k] = order[k - 1];
      order[k] = e;
    }
  } else {
    std::sort(order.begin(), order.end());
  }
  return nearest_by(ray, tmin, tmax, [&](auto& test) {
    double bound = tmax;
    for (const auto& [entry, p] : order) {
      // The margin covers the rounding of the slab distances.
      if (entry > bound + 1e-9 * std::abs(bound)) break;
      bound = test(p, ps_.leaf_slot_of(p));
    }
  });
}

Color segment_transmittance(const Scene& scene, const Ray& seg, std::vector<Crossing>& crossings) {
  if (crossings.empty()) return Color(1.0);
  // Sorted so the product is formed in the same order whatever the
  // traversal (bit-identical images with and without boxes).
  std::sort(crossings.begin(), crossings.end(), [](const Crossing& a, const Crossing& b) {
    return a.t != b.t ? a.t < b.t : a.leaf < b.leaf;
  });
  const double len = glm::length(seg.dir);
  Color tp(1.0);
  // (object, t where the segment entered it) for bodies currently inside.
  thread_local std::vector<std::pair<int, double>> inside;
  inside.clear();
  auto absorb = [&](int obj, double t0, double t1) {
    const Material& m = scene.materials[scene.objects[obj].material];
    if (m.absorption != Color(0.0)) tp *= beer(m.absorption, (t1 - t0) * len);
  };
  for (const Crossing& c : crossings) {
    const Material& m = scene.materials[scene.objects[c.leaf].material];
    const double cos_i = glm::dot(seg.dir, c.normal) / len;
    const bool entering = cos_i < 0;
    // eq. (3): (1 - r_a)(1 - r_b), straight path, refraction ignored.
    const double r = entering ? fresnel(cos_i, 1.0, m.ior) : fresnel(cos_i, m.ior, 1.0);
    if (r >= 1.0) return Color(0.0);
    tp *= (1.0 - r);
    auto it = std::find_if(inside.begin(), inside.end(),
                           [&](const auto& e) { return e.first == c.leaf; });
    if (entering) {
      if (it == inside.end()) inside.emplace_back(c.leaf, c.t);
    } else {
      absorb(c.leaf, it == inside.end() ? 0.0 : it->second, c.t);
      if (it != inside.end()) inside.erase(it);
    }
  }
  for (const auto& [obj, t0] : inside) absorb(obj, t0, 1.0);
  return tp;
}

Color Tracer::transmittance(const Vec3& p, const Vec3& ng, int light, int receiver,
                            KnownShadows* known) {
  const Vec3 lp = ps_.scene.lights[light].position;
  const Vec3 origin = shadow_origin(p, ng, light);
  if (known) {
    if (const std::optional<Color> t = known->transmittance(p, origin, light)) return *t;
  }
  // Configuration IV: containment in shadow volumes (paper §4.1), unless
  // the frame's points cast rays (PreparedScene::point_shadows_by_rays).
  if (ps_.points_search_volumes()) {
    return volume_transmittance(ps_, origin, light, receiver, stats_, &last_occluder(light));
  }
  const Ray seg{origin, lp - origin};  // t in (0, 1) spans the segment
  thread_local std::vector<Crossing> crossings;
  crossings.clear();
  if (shadow_crossings(seg, light, crossings, receiver)) return Color(0.0);
  return segment_transmittance(ps_.scene, seg, crossings);
}

bool Tracer::shadow_crossings(const Ray& seg, int light, std::vector<Crossing>& crossings,
                              int receiver) {
  ++stats_.rays_shadow;
  bool opaque = false;
  const PrimRange own = own_solid_skip(ps_.own_solid, receiver, light);
  // The faces an opaque closed solid turns away from the light never stop
  // it alone (hidden_faces.h).
  const uint8_t cull = light < kCullLights ? cull_light(light) : 0;
  // The skips are decided before the primitive's leaf copy is read: from
  // the receiver's range and a byte a primitive (PreparedScene::culls), not
  // from the copy's own cache lines (SPD tetra level 9, where about half
  // the faces a shadow ray meets are turned away from its light: render
  // 0.963x).
  auto test = [&](int prim, int slot = -1) {
    if (own.has(prim) || (ps_.culls[prim] & cull)) return 1.0;
    const LeafPrim* lp = ps_.leaf_prim_at(slot);
    ++stats_.tests_ray_object;
    if (lp && lp->stops_light) {
      if (!leaf_any(*lp, seg, 0.0, 1.0)) return 1.0;
      opaque = true;
      last_occluder(light) = prim;
      return -1.0;
    }
    if (ps_.stops_light[prim]) {
      // An opaque primitive (its crossings are all its object's): whether it
      // is crossed at all decides, and no crossing is kept.
      if (!intersect_any(ps_.prims, prim, seg, 0.0, 1.0)) return 1.0;
      opaque = true;
      last_occluder(light) = prim;
      return -1.0;
    }
    const size_t before = crossings.size();
    intersect_all(ps_.prims, prim, seg, 0.0, 1.0, crossings);
    for (size_t i = before; i < crossings.size(); ++i) {
      const Material& m = ps_.material_of(crossings[i].leaf);
      if (m.t <= 0.0) {
        opaque = true;  // eq. (2): an opaque occluder stops everything
        last_occluder(light) = prim;
        return -1.0;
      }
    }
    return 1.0;
  };
  if (const int cached = last_occluder(light); cached >= 0) {
    if (test(cached, ps_.leaf_slot_of(cached)) < 0) return true;
    crossings.clear();  // seen again in the full search below
  }
  if (ps_.bvh_for_shadows) {
    traverse_bvh<false>(ps_.bvh, seg, 0.0, 1.0, test);
  } else {
    for (int i = 0; i < static_cast<int>(ps_.prims.prims.size()) && !opaque; ++i) test(i);
  }
  return opaque;
}

Color Tracer::trace(const Ray& ray, double tmin, int depth, double weight, const Material* medium) {
  const auto hit = nearest(ray, tmin, kInf);
  if (!hit) return ps_.scene.background;
  return shade(ray, *hit, depth, weight, medium);
}

Color Tracer::shade(const Ray& ray, const SurfaceHit& hit, int depth, double weight,
                    const Material* medium, KnownShadows* known) {
  const Scene& scene = ps_.scene;
  const Crossing& c = hit.crossing;
  const Material& m = ps_.material_of(c.leaf);
  // Lambert-Beer along the ray's own path inside a medium.
  Color atten(1.0);
  if (medium && medium->absorption != Color(0.0)) atten = beer(medium->absorption, hit.t);
  const double w = weight * max_component(atten);

  const Vec3 p = ray.origin + hit.t * ray.dir;
  const Vec3 ng = c.normal;  // outward, geometric
  const bool entering = glm::dot(ray.dir, ng) < 0;
  Vec3 n = shading_normal(ps_.prims, ps_.prims.prims[hit.prim], c);
  if (glm::dot(n, ray.dir) > 0) n = -n;  // face the incoming ray
  const Vec3 v = -ray.dir;

  Color result = ps_.ambient * m.kd * m.color;
  cache_level_ = std::min(depth, kCacheLevels) - 1;
  for (int j = 0; j < static_cast<int>(scene.lights.size()); ++j) {
    const Vec3 l = glm::normalize(scene.lights[j].position - p);
    const double ndl = glm::dot(n, l);
    if (ndl <= 0) continue;  // light behind the shaded side
    if (m.kd == 0 && m.ks == 0) continue;
    const Color tp = transmittance(p, ng, j, hit.prim, known);
    if (tp == Color(0.0)) continue;
    const Vec3 r = 2.0 * ndl * n - l;
    const double spec = m.ks > 0 ? m.ks * std::pow(std::max(0.0, glm::dot(r, v)), m.shine) : 0.0;
    result += ps_.emission[j] * tp * (m.kd * ndl * m.color + Color(spec));
  }

  if (depth < kMaxDepth) {
    auto spawn = [&](const Vec3& dir, double coef, const Material* med) {
      return trace(Ray{offset(p, ng, dir), dir}, 0.0, depth + 1, w * coef, med);
    };
    if (m.ks > 0 && w * m.ks >= kMinWeight) {
      ++stats_.rays_reflected;
      result += m.ks * spawn(reflect(ray.dir, n), m.ks, medium);
    }
    if (m.t > 0 && w * m.t >= kMinWeight) {
      const double eta = entering ? 1.0 / m.ior : m.ior;
      if (const auto dir = refract(ray.dir, n, eta)) {
        ++stats_.rays_refracted;
        result += m.t * spawn(*dir, m.t, entering ? &m : nullptr);
      } else {
        // Total internal reflection: a reflected ray of the same weight T.
        ++stats_.rays_reflected;
        result += m.t * spawn(reflect(ray.dir, n), m.t, medium);
      }
    }
  }
  return atten * result;
}

namespace {

// Deterministic jitter from the pixel and sample index only, so a pixel's
// value never depends on the band or thread that renders it.
uint64_t mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
double unit(uint64_t x) { return static_cast<double>(x >> 11) * (1.0 / 9007199254740992.0); }

}  // namespace

void raytrace_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int y,
                   Image& out, Stats& stats, CostBuffer* cost) {
  CostMeter meter(cost, stats);
  meter.set_row(y);
  Tracer tracer(ps, stats);
  const CameraFrame& cam = ps.camera;
  const int n = std::max(1, params.spp);
  // Eye directions first, then their rays, a run of pixels at a time:
  // made in the loop, each direction's square root and division
  // (CameraFrame::direction) were a chain of ~35 cycles that the next walk
  // waited for, since the walk before it filled the processor's window
  // (perf: 40% of raytrace_rows' own time on SPD s1 tetra). Made apart,
  // they overlap each other. The same operations: the same directions, bit
  // for bit. The run holds about kAhead samples (at least a pixel's).
  constexpr int kAhead = 512;
  const int per_pixel = n * n;
  const int run = std::max(1, kAhead / per_pixel);
  thread_local std::vector<Vec3> dirs;
  dirs.resize(static_cast<size_t>(run) * per_pixel);
  for (int x0 = 0; x0 < cam.width; x0 += run) {
    const int x1 = std::min(cam.width, x0 + run);
    Vec3* d = dirs.data();
    for (int x = x0; x < x1; ++x) {
      for (int sy = 0; sy < n; ++sy) {
        for (int sx = 0; sx < n; ++sx) {
          double fx = 0.5, fy = 0.5;
          if (n > 1) {
            const uint64_t h = mix((static_cast<uint64_t>(y) << 32) ^ static_cast<uint64_t>(x) ^
                                   mix(static_cast<uint64_t>(sy * n + sx)));
            fx = (sx + unit(h)) / n;
            fy = (sy + unit(mix(h))) / n;
          }
          *d++ = cam.direction(x + fx, y + fy);
        }
      }
    }
    const Vec3* dir = dirs.data();
    for (int x = x0; x < x1; ++x) {
      Color sum(0.0);
      for (int k = 0; k < per_pixel; ++k) {
        ++stats.rays_eye;
        const Ray ray{cam.from, *dir++};
        sum += tracer.trace(ray, cam.hither, 1, 1.0, nullptr);
      }
      sum /= static_cast<double>(per_pixel);
      store_pixel(out, band, x, y, sum);
      meter.charge(x);
      meter.mark_traced(x, true);
    }
  }
  stats.pixels_total += cam.width;
  stats.pixels_ray_traced += cam.width;
}

}  // namespace locus
