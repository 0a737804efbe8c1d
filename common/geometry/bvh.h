// A bounding-volume hierarchy over primitive boxes, built with the surface
// area heuristic (binned). This is the "modern baseline" hierarchy used by
// --boxes eye+shadow in the ray tracer; the paper's own hierarchy of boxes
// (METHOD.md §7) builds on the same nodes.
#pragma once

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common/base/check.h"
#include "common/geometry/geometry.h"

namespace locus {

struct BvhNode {
  Aabb box;
  int first = 0;  // leaf: first index into Bvh::order; inner: right child
  int count = 0;  // > 0 for leaves; inner nodes have their left child at i + 1
};

struct Bvh {
  std::vector<BvhNode> nodes;
  std::vector<int> order;  // primitive indices, leaves refer to ranges
};

Bvh build_bvh(const std::vector<Aabb>& bounds);

// Precomputed reciprocal direction for slab tests.
struct RayInv {
  Vec3 origin, inv;
  explicit RayInv(const Ray& r) : origin(r.origin), inv(1.0 / r.dir.x, 1.0 / r.dir.y, 1.0 / r.dir.z) {}
};

// The slab test: does the ray meet box b for some t in [tmin, tmax]? A NaN
// slab distance (origin on a slab's plane, direction parallel to it) never
// moves tmin or tmax. hit_box_scalar is the plain loop; hit_box gives the
// same answers, with SSE2 where the build has it.
inline bool hit_box_scalar(const Aabb& b, const RayInv& r, double tmin, double tmax) {
  for (int a = 0; a < 3; ++a) {
    double t0 = (b.lo[a] - r.origin[a]) * r.inv[a];
    double t1 = (b.hi[a] - r.origin[a]) * r.inv[a];
    if (t0 > t1) std::swap(t0, t1);
    if (t0 > tmin) tmin = t0;
    if (t1 < tmax) tmax = t1;
    if (tmin > tmax) return false;
  }
  return true;
}

inline bool hit_box(const Aabb& b, const RayInv& r, double tmin, double tmax) {
#if defined(__SSE2__)
  // x and y in one register, z in the low lane of another: branchless, and
  // 12-16% faster than the scalar loop on whole ray-traced renders of SPD
  // balls and rings (docs/renderer.md, "SIMD"). Each min/max takes its
  // operands in the order that gives the scalar loop's comparisons exactly
  // (MINPD/MAXPD return the second operand when either is NaN or they are
  // equal): near = t1 < t0 ? t1 : t0, far = t0 > t1 ? t0 : t1,
  // tmin = near > tmin ? near : tmin, tmax = far < tmax ? far : tmax.
  const __m128d o = _mm_loadu_pd(&r.origin.x), inv = _mm_loadu_pd(&r.inv.x);
  const __m128d t0 = _mm_mul_pd(_mm_sub_pd(_mm_loadu_pd(&b.lo.x), o), inv);
  const __m128d t1 = _mm_mul_pd(_mm_sub_pd(_mm_loadu_pd(&b.hi.x), o), inv);
  const __m128d near = _mm_min_pd(t1, t0), far = _mm_max_pd(t0, t1);
  const __m128d z0 = _mm_set_sd((b.lo.z - r.origin.z) * r.inv.z);
  const __m128d z1 = _mm_set_sd((b.hi.z - r.origin.z) * r.inv.z);
  __m128d lo = _mm_max_sd(near, _mm_set_sd(tmin));
  __m128d hi = _mm_min_sd(far, _mm_set_sd(tmax));
  lo = _mm_max_sd(_mm_unpackhi_pd(near, near), lo);
  hi = _mm_min_sd(_mm_unpackhi_pd(far, far), hi);
  lo = _mm_max_sd(_mm_min_sd(z1, z0), lo);
  hi = _mm_min_sd(_mm_max_sd(z0, z1), hi);
  return !(_mm_cvtsd_f64(lo) > _mm_cvtsd_f64(hi));
#else
  return hit_box_scalar(b, r, tmin, tmax);
#endif
}

// Where the ray enters box b: the largest of tmin and the slabs' near
// distances (a NaN slab distance is skipped). No crossing with anything
// inside the box lies nearer; the ray may miss the box all the same.
inline double box_entry(const Aabb& b, const RayInv& r, double tmin) {
  double t = tmin;
  for (int a = 0; a < 3; ++a) {
    const double t0 = (b.lo[a] - r.origin[a]) * r.inv[a];
    const double t1 = (b.hi[a] - r.origin[a]) * r.inv[a];
    const double near = t0 < t1 ? t0 : t1;
    if (near > t) t = near;
  }
  return t;
}

// The walk's stack. A walk holds at most one pending sibling per level
// below the root, so it holds every hierarchy build_bvh makes (its depth is
// at most kMaxDepth, bvh.cpp); a deeper one, built by hand, trips the
// LOCUS_CHECK in walk_bvh instead of writing past the array.
inline constexpr int kBvhWalkStack = 128;

// The one walk over the hierarchy, depth first from the root; the ray
// tracer's (traverse_bvh), the shadow search's, the front/back relations'
// and the span shadows' walks (a box's shadow volume against a span, with
// candidate narrowing) are this one with their own callables, inlined.
// `enter(ni)` says whether node ni's subtree is walked. At an entered leaf,
// `visit(prim)` is called for its primitives in order, and ends the walk by
// returning false. An entered inner node's children come next: the right one
// (nodes[ni].first) before the left one (ni + 1) if `right_first(ni)`.
// Returns false if `visit` ended the walk.
template <typename Enter, typename Visit, typename RightFirst>
bool walk_bvh(const Bvh& bvh, Enter&& enter, Visit&& visit, RightFirst&& right_first) {
  if (bvh.nodes.empty()) return true;
  int stack[kBvhWalkStack];
  int sp = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const int ni = stack[--sp];
    if (!enter(ni)) continue;
    const BvhNode& n = bvh.nodes[ni];
    if (n.count > 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {
        if (!visit(bvh.order[i])) return false;
      }
      continue;
    }
    LOCUS_CHECK(sp + 2 <= kBvhWalkStack);
    const int left = ni + 1, right = n.first;
    if (right_first(ni)) {
      stack[sp++] = left;
      stack[sp++] = right;
    } else {
      stack[sp++] = right;
      stack[sp++] = left;
    }
  }
  return true;
}

// walk_bvh with the left child always first.
template <typename Enter, typename Visit>
bool walk_bvh(const Bvh& bvh, Enter&& enter, Visit&& visit) {
  return walk_bvh(bvh, enter, visit, [](int) { return false; });
}

// Visits the primitives whose leaf boxes the ray meets in (tmin, tmax), the
// near child first. `visit(prim)` returns the possibly shortened tmax, or a
// negative value to stop the traversal.
template <typename F>
void traverse_bvh(const Bvh& bvh, const Ray& ray, double tmin, double tmax, F&& visit) {
  const RayInv ri(ray);
  const bool neg[3] = {ray.dir.x < 0, ray.dir.y < 0, ray.dir.z < 0};
  walk_bvh(
      bvh, [&](int ni) { return hit_box(bvh.nodes[ni].box, ri, tmin, tmax); },
      [&](int prim) {
        const double t = visit(prim);
        if (t < 0) return false;
        tmax = t;
        return true;
      },
      [&](int ni) {
        // The child whose centre lies first along the ray's direction, on
        // the axis that separates the two centres most.
        const Vec3 d = bvh.nodes[bvh.nodes[ni].first].box.centre() - bvh.nodes[ni + 1].box.centre();
        const int major = std::abs(d.x) > std::abs(d.y) ? (std::abs(d.x) > std::abs(d.z) ? 0 : 2)
                                                        : (std::abs(d.y) > std::abs(d.z) ? 1 : 2);
        return (d[major] < 0) != neg[major];
      });
}

}  // namespace locus
