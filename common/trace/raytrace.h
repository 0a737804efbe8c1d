// The Whitted ray tracer of SHADING.md: configuration I of the paper when
// every ray tests every object, the BVH baseline otherwise. The local method
// (scanline + ray tracing only where needed) calls shade() on spans whose
// visible surface it already knows.
#pragma once

#include <optional>

#include "common/base/cost.h"
#include "common/base/image.h"
#include "common/base/params.h"
#include "common/prepare/prepared.h"

namespace locus {

struct SurfaceHit {
  double t = 0;
  int prim = -1;
  Crossing crossing;
};

// t_pj already known to the caller for the point being shaded: the local
// method's scanline pass finds the shadows of its spans before shading
// (paper §3.2), so shade() asks it instead of searching.
class KnownShadows {
 public:
  virtual ~KnownShadows() = default;
  // `p` is the shaded point, `origin` the start of its shadow segment (p
  // offset off the surface towards the light's side, as a shadow ray).
  // nullopt: not known here after all (the caller searches itself).
  virtual std::optional<Color> transmittance(const Vec3& p, const Vec3& origin, int light) = 0;
};

// Paper eqs. (2), (3): the product of (1 - r) over the crossings of the
// segment `seg` (t in (0, 1), from the shadow-ray origin to the light) with
// transparent surfaces, and exp(-q d) over the lengths inside them.
// `crossings` are sorted first (by t, then object), so the product is formed
// in the same order whoever collected them.
Color segment_transmittance(const Scene& scene, const Ray& seg, std::vector<Crossing>& crossings);

class Tracer {
 public:
  Tracer(const PreparedScene& ps, Stats& stats)
      : ps_(ps),
        stats_(stats),
        last_occluder_(ps.scene.lights.size() * kCacheLevels, -1) {}

  // Nearest surface along the ray in (tmin, tmax). Ties go to the lower
  // primitive index, so every traversal order gives the same answer.
  std::optional<SurfaceHit> nearest(const Ray& ray, double tmin, double tmax);
  // The same, among the primitives `prims` only (the caller knows that no
  // other one can be met), with the same tie rule.
  std::optional<SurfaceHit> nearest_among(const Ray& ray, double tmin, double tmax,
                                          const std::vector<int>& prims);

  // Fraction of light `light` reaching p (paper eqs. (2), (3)), per channel.
  // `ng` is the outward geometric normal at p, used to offset the origin.
  // `receiver` is the primitive p lies on (-1: unknown), whose list of
  // possible occluders narrows the search with shadow volumes; `known`, if
  // given, already knows the answer (scanline spans).
  Color transmittance(const Vec3& p, const Vec3& ng, int light, int receiver = -1,
                      KnownShadows* known = nullptr);

  // Where a shadow ray to light `light` from p starts: p moved off its
  // surface (outward geometric normal ng) towards the light's side.
  Vec3 shadow_origin(const Vec3& p, const Vec3& ng, int light) const {
    return offset(p, ng, ps_.scene.lights[light].position - p);
  }

  // A shadow ray through the boxes along `seg` (t in (0, 1) from the
  // shadow-ray origin to light `light`): its crossings with transparent
  // surfaces appended to `crossings`; true, and the search stopped, where an
  // opaque occluder blocks it (eq. (2)). `receiver` (-1: none): the face
  // whose point the origin is shadow_origin's offset of, whose own closed
  // solid the ray then need not search (own_solid_skip, hidden_faces.h).
  bool shadow_crossings(const Ray& seg, int light, std::vector<Crossing>& crossings,
                        int receiver = -1);

  // Radiance along a ray; depth 1 is the primary ray. `medium` is the
  // material whose body the ray travels in (nullptr outside).
  Color trace(const Ray& ray, double tmin, int depth, double weight, const Material* medium);

  // Shading of a known hit (SHADING.md "Materials"). `known` gives t_pj of
  // this hit, if the caller already knows it.
  Color shade(const Ray& ray, const SurfaceHit& hit, int depth, double weight,
              const Material* medium, KnownShadows* known = nullptr);

 private:
  Vec3 offset(const Vec3& p, const Vec3& ng, const Vec3& dir) const {
    return p + (glm::dot(dir, ng) >= 0 ? ps_.eps : -ps_.eps) * ng;
  }

  // nearest() over the primitives that visit(test) passes to test.
  template <class Visit>
  std::optional<SurfaceHit> nearest_by(const Ray& ray, double tmin, double tmax, Visit&& visit);

  const PreparedScene& ps_;
  Stats& stats_;
  // Per light, the primitive that last blocked it (Haines' shadow cache):
  // neighbouring samples are usually shadowed by the same object, so it is
  // tested first. Any opaque crossing gives t_pj = 0, so the answer does not
  // depend on which occluder is found.
  // Per level of the ray tree (eye points, their reflections' points, ...)
  // and light: neighbouring samples' points on one level are neighbours,
  // those of two levels are not.
  static constexpr int kCacheLevels = 4;
  int cache_level_ = 0;
  std::vector<int> last_occluder_;
  int& last_occluder(int light) { return last_occluder_[cache_level_ * ps_.scene.lights.size() + light]; }
};

// The ray-tracing path of render_band (--method raytrace). `cost`, if
// given, gets each pixel's share of `stats` (cost.h); every pixel is traced.
void raytrace_rows(const PreparedScene& ps, const RenderParams& params, const Band& band,
                   int row, Image& out, Stats& stats, CostBuffer* cost = nullptr);

}  // namespace locus
