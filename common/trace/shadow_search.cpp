#include "common/trace/shadow_search.h"

#include <algorithm>

#include "common/geometry/bvh.h"
#include "common/geometry/pencil.h"
#include "common/prepare/prepared.h"
#include "common/prepare/shadow_candidates.h"
#include "common/prepare/shadow_volume.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace {

// A point tests its receiver's candidate list directly when it is this
// long at most; a longer one through the hierarchy. Measured (callgrind, s2 rings at 256², --aa 4): 8 -> 3.57G
// instructions, 16 -> 3.20G, 32 -> 3.01G, 64 -> 3.00G; the images are
// pixel-identical (the occluder set is the same, only the visiting order).
constexpr int kWalkAbove = 32;

}  // namespace

bool exact_test(const PreparedScene& ps, int prim, const Ray& seg, std::vector<Crossing>& crossings,
                Stats& stats) {
  ++stats.tests_ray_object;
  // An opaque primitive: any crossing is the answer, and its normal is
  // never used; from its leaf copy where it has one (leaf_prims.h).
  if (ps.stops_light[prim]) {
    if (const LeafPrim* lp = ps.leaf_prim_of(prim)) return leaf_any(*lp, seg, 0.0, 1.0);
    return intersect_any(ps.prims, prim, seg, 0.0, 1.0);
  }
  const size_t before = crossings.size();
  intersect_all(ps.prims, prim, seg, 0.0, 1.0, crossings);
  for (size_t i = before; i < crossings.size(); ++i) {
    const Material& m = ps.material_of(crossings[i].leaf);
    if (m.t <= 0.0) return true;
  }
  return false;
}

// The plane touches the solid where it is nearest o: a sphere's tangent
// plane; a cone's along its generator on o's side.
bool beyond_support(const PrimitiveSet& prims, int prim, const Vec3& o, const Vec3& l) {
  if (!plain_quadric(prims, prim)) return false;
  const PrimRef& ref = prims.prims[prim];
  if (ref.kind == PrimKind::kSphere) {
    const SpherePrim& sp = prims.spheres[ref.index];
    const Vec3 v = o - sp.s.center;
    const double d = glm::length(v);
    const double r = sp.s.radius * d;  // both sides times |v|
    return d > sp.s.radius && glm::dot(v, l - sp.s.center) > r;
  }
  const ConePrim& c = prims.cones[ref.index];
  // n = e - k a (e: o's radial direction): n . (x - base) <= r0 over the
  // solid, since its radius at axial s is r0 + k s.
  const Vec3 v = o - c.c.base;
  const Vec3 w = v - glm::dot(v, c.axis.a) * c.axis.a;
  const double d = glm::length(w);
  if (!(d > 0)) return false;
  const Vec3 n = w / d - c.axis.k * c.axis.a;
  const double r0 = c.c.base_radius;
  return glm::dot(n, v) > r0 && glm::dot(n, l - c.c.base) > r0;
}

Color volume_transmittance(const PreparedScene& ps, const Vec3& origin, int light, int receiver,
                           Stats& stats, int* last_occluder) {
  const LightVolumes& lv = ps.volumes->lights[light];
  const Ray seg{origin, lv.position - origin};
  // The crossings of transparent occluders met so far (eqs. (2), (3)).
  thread_local std::vector<Crossing> crossings;
  crossings.clear();
  bool ray = false;
  bool shadowed = false;
  // A candidate whose volume holds the point: true if it gives t_pj = 0,
  // because the volume is an opaque one's (no ray needed) or the exact test of a
  // curved body, CSG or transparent occluder met an opaque surface. The
  // exact test runs at once, so an opaque curved body ends the search as
  // early as a shadow ray's first hit would.
  auto inside_occluder = [&](int a, bool decides) {
    if (!decides) {
      if (!ray) ++stats.rays_shadow;
      ray = true;
      if (!exact_test(ps, a, seg, crossings, stats)) return false;
    }
    if (last_occluder) *last_occluder = a;
    shadowed = true;
    return true;
  };
  // Containment in one candidate's volumes, then the above.
  auto occluder = [&](int a) {
    const LightVolumes::Occluder& oc = lv.occluders[a];
    if (oc.bound >= 0) {
      ++stats.tests_shadow_volume;
      if (!lv.set.contains(oc.bound, origin, lv.slack)) return false;
    }
    bool inside = false;
    for (int v = oc.first; v < oc.first + oc.count && !inside; ++v) {
      ++stats.tests_shadow_volume;
      inside = lv.set.contains(v, origin, oc.decides ? 0.0 : lv.slack);
    }
    return inside && inside_occluder(a, oc.decides);
  };
  // The occluder that shadowed the previous point is likely to shadow this
  // one too (neighbouring points); any opaque one gives t_pj = 0. It is not
  // tested twice (its crossings would count twice).
  int first = -1;
  if (last_occluder && *last_occluder >= 0) {
    first = *last_occluder;
    if (occluder(first)) return Color(0.0);
  }
  // Whether candidate a is to be skipped: the one tested first, or the
  // receiver itself where it cannot shadow the origin (beyond_support).
  auto skip = [&](int a) {
    return a == first || (a == receiver && beyond_support(ps.prims, receiver, origin, lv.position));
  };
  const int* cb = nullptr;
  const int* ce = nullptr;
  const CandidateList::Direct* db = nullptr;
  if (receiver >= 0 && ps.volumes->search) {
    const CandidateList& list = receiver_candidates(ps, light, receiver);
    const ReceiverParts* rp = ps.volumes->parts.empty() ? nullptr : &ps.volumes->parts[receiver];
    if (rp && rp->count > 0) {
      // The slice of the receiver that holds the origin.
      const double s = glm::dot(origin - rp->base, rp->scaled_axis) * rp->count;
      const int q = clamped_floor(s, 0, rp->count - 1);
      cb = list.part_ids.data() + list.part_first[q];
      ce = list.part_ids.data() + list.part_first[q + 1];
      db = list.part_direct.data() + list.part_first[q];
    } else {
      cb = list.ids.data();
      ce = cb + list.ids.size();
      db = list.direct.data();
    }
  }
  if (cb && ce - cb <= kWalkAbove) {
    const CandidateList::Direct* d = db;
    for (const int* c = cb; c != ce; ++c, ++d) {
      if (skip(*c)) continue;
      if (d->count < 0) {
        if (occluder(*c)) return Color(0.0);
        continue;
      }
      // The candidate's one convex volume, as occluder() would test it.
      ++stats.tests_shadow_volume;
      if (lv.set.inside_planes(d->first, d->count, origin, d->decides ? 0.0 : lv.slack) &&
          inside_occluder(*c, d->decides)) {
        return Color(0.0);
      }
    }
  } else if (!ps.bvh.nodes.empty()) {
    // Top down through the hierarchy: outside a box's shadow volume,
    // nothing in the box shadows the point (paper §4.1). The box's volume
    // (the points whose segment to the light meets the box) holds the point
    // exactly when the segment meets the box, which three slab tests decide
    // for less than the volume's 7 to 9 planes; the near child first.
    traverse_bvh(ps.bvh, seg, 0.0, 1.0, [&](int a) {
      ++stats.tests_shadow_volume;
      if (skip(a) || (cb && !std::binary_search(cb, ce, a))) return 1.0;
      return occluder(a) ? -1.0 : 1.0;
    });
    if (shadowed) return Color(0.0);
  }
  return segment_transmittance(ps.scene, seg, crossings);
}

}  // namespace locus
