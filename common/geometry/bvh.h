// A bounding-volume hierarchy over primitive boxes, built with the surface
// area heuristic (binned). This is the "modern baseline" hierarchy used by
// --boxes eye+shadow in the ray tracer; the paper's own hierarchy of boxes
// (METHOD.md §7) builds on the same nodes. Two walks: walk_bvh over the
// binary nodes for region queries, traverse_bvh over their 4-wide float
// form for rays (docs/renderer.md, "The ray kernel against Embree").
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// The 8-wide walk: AVX2 code in an SSE2 build, run where the processor has
// AVX2 (wide8_walk_available). GCC on x86-64 (the target pragma below);
// elsewhere the 4-wide walk alone.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(LOCUS_NO_WIDE8)
#define LOCUS_WIDE8 1
#include <immintrin.h>
#else
#define LOCUS_WIDE8 0
#endif

#include "common/base/check.h"
#include "common/geometry/geometry.h"

namespace locus {

struct BvhNode {
  Aabb box;
  int first = 0;  // leaf: first index into Bvh::order; inner: right child
  int count = 0;  // > 0 for leaves; inner nodes have their left child at i + 1
};

// The ray walk's form of the same hierarchy (traverse_bvh): the binary tree
// collapsed into nodes of up to 4 children, each child's box in float,
// rounded outward from the double box, and stored by plane so that one SSE
// pass tests all four. Child slot k: `count[k]` > 0 is a leaf (`ref[k]` its
// first index into Bvh::order, as BvhNode), 0 an inner node (`ref[k]` its
// index in Bvh::wide), -1 an empty slot, whose box (lo = +inf, hi = -inf)
// no ray meets.
// BvhWideNodeN<8> is the same with 8 children, for the AVX2 walk.
template <int W>
struct BvhWideNodeN {
  alignas(4 * W) float planes[3][2][W];  // [axis][0: lo, 1: hi][child]
  int ref[W];
  int count[W];
};
using BvhWideNode = BvhWideNodeN<4>;
using BvhWideNode8 = BvhWideNodeN<8>;

struct Bvh {
  std::vector<BvhNode> nodes;  // the binary tree: the hierarchy of boxes of §4.1
  std::vector<int> order;      // primitive indices, leaves refer to ranges
  // The same leaves for rays, wide[0] or wide8[0] the root: 8-wide where
  // the processor has AVX2 (wide8_walk_available), 4-wide elsewhere.
  // build_bvh makes only the one traverse_bvh walks (it walks wide8 when
  // that is there).
  std::vector<BvhWideNode> wide;
  std::vector<BvhWideNode8> wide8;
};

// Builds the binary tree and its 8-wide form where the processor has
// AVX2, its 4-wide form elsewhere; a large tree's subtrees on up to
// `threads` threads, the same tree for any count.
Bvh build_bvh(const std::vector<Aabb>& bounds, int threads = 1);

// Fills bvh.wide from bvh.nodes: each inner node takes the children of its
// largest inner children until it has 4 (build_bvh calls it; tests that
// build a tree by hand call it themselves).
void build_wide(Bvh& bvh);
// The same, 8-wide, into bvh.wide8 (whatever the processor).
void build_wide8(Bvh& bvh);
// Whether this processor runs the 8-wide walk (AVX2), and the build was
// made for x86-64.
bool wide8_walk_available();

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

// The region walk over the binary hierarchy, depth first from the root:
// the front/back relations' and the span shadows' walks (a box's shadow
// volume against a hull, a span or a group of lines, paper §4.1, with
// per-node data indexed by node) are this one with their own callables,
// inlined. Rays and segments take the 4-wide walk, traverse_bvh, instead.
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

// The ray in the form the 4-wide box test takes (wide_hits): origin and
// reciprocal direction in float, which of each axis' planes the ray meets
// first, and the slack that makes the float test conservative. The float
// slab distance of a plane p, fl(fl(p - o_f) * inv_f), is within 3 units of
// float rounding (relative, 2^-24 each) of the exact distance from the
// float origin o_f; the exact origin o = o_f + r moves the distance on axis
// a by r_a / d_a. So a near plane's distance is taken with the reciprocal
// scaled by 1 - kWideRel (inv_near) and a far plane's with 1 + kWideRel
// (inv_far): a positive distance comes out no larger (near) or no smaller
// (far) than the exact one from o_f, and a negative one stays negative,
// where a near plane's cannot raise the entry above tmin, which is never
// negative, and a far plane's is within the origin's shift of 0 (the
// ray's exact far distance is at least tmin >= 0). The entry is then
// lowered by twice the largest |r_a / d_a| (slack, with 1% to spare for
// those negative far distances), and a box the exact ray meets in
// [tmin, tmax] is never missed; the exact tests of its primitives decide
// (the hierarchy only ever adds candidates). The scaled reciprocals take
// the relative margin out of each node's test, where it was six more
// operations, three of them in the chain from the slab distances to the
// mask (docs/renderer.md "The box test's margin in the reciprocals").
struct WideRay {
  static constexpr float kWideRel = 1.0f / (1 << 20);  // 16 units of float rounding
  float origin[3];
  // The float reciprocal of the direction, scaled by 1 -+ kWideRel (above).
  float inv_near[3], inv_far[3];
  int near_plane[3];  // 0: lo, 1: hi
  float slack;
  explicit WideRay(const Ray& r);
};

// Inline: one per ray walk.
inline WideRay::WideRay(const Ray& r) {
  double shift = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double inv_d = 1.0 / r.dir[a];
    origin[a] = static_cast<float>(r.origin[a]);
    near_plane[a] = std::signbit(inv_d) ? 1 : 0;
    float inv;
    if (std::isinf(inv_d)) {
      // Parallel to the slabs: the distances are infinite or NaN, and their
      // signs are those of the exact origin's (rounding is monotonic and
      // the planes are rounded outward), so no shift.
      inv = static_cast<float>(inv_d);
    } else if (std::abs(inv_d) > 1e30) {
      // Nearly parallel: this axis is not tested (a NaN distance), which is
      // conservative, rather than rounded to an infinite reciprocal.
      inv = std::numeric_limits<float>::quiet_NaN();
    } else {
      inv = static_cast<float>(inv_d);
      // The float origin's error along the ray.
      shift = std::max(shift, std::abs((r.origin[a] - static_cast<double>(origin[a])) * inv_d));
    }
    // Infinite and NaN reciprocals stay so.
    inv_near[a] = static_cast<float>(static_cast<double>(inv) * (1.0 - kWideRel));
    inv_far[a] = static_cast<float>(static_cast<double>(inv) * (1.0 + kWideRel));
  }
  // Twice the shift, rounded up generously; kept finite (an infinite slack
  // would turn the test's infinite bounds into NaN).
  slack = static_cast<float>(std::min(2.0 * 1.01 * shift + 1e-30, 1e30));
}

// The largest float not above x, and the smallest not below (a NaN stays
// NaN). Inline, by the float's bits: std::nextafter is a library call, and
// the ray walk rounds its bound up each time a hit shortens it.
inline float float_down(double x) {
  const float f = static_cast<float>(x);
  if (!(static_cast<double>(f) > x)) return f;
  if (f == 0.0f) return -std::numeric_limits<float>::denorm_min();
  const uint32_t b = std::bit_cast<uint32_t>(f);
  return std::bit_cast<float>(f > 0.0f ? b - 1 : b + 1);
}
inline float float_up(double x) {
  const float f = static_cast<float>(x);
  if (!(static_cast<double>(f) < x)) return f;
  if (f == 0.0f) return std::numeric_limits<float>::denorm_min();
  const uint32_t b = std::bit_cast<uint32_t>(f);
  return std::bit_cast<float>(f > 0.0f ? b + 1 : b - 1);
}

// The ray walk's stack: an entered node leaves at most W - 1 children
// pending, and a wide tree is no deeper than the binary one (bvh.cpp).
template <int W>
inline constexpr int kBvhRayStackN = (W - 1) * kBvhWalkStack;
inline constexpr int kBvhRayStack = kBvhRayStackN<4>;

// The lanes of a W-wide node's box test (bvh_walk.inc, wide_hits_lanes):
// the register type and the few operations the test makes, one intrinsic
// each. WideOps<4> is SSE2 (or, without SSE2, no lanes: the plain loop of
// wide_hits_scalar); WideOps<8> is AVX2, below.
template <int W>
struct WideOps;

#if defined(__SSE2__)
template <>
struct WideOps<4> {
  static constexpr bool kLanes = true;
  using V = __m128;
  static V set1(float x) { return _mm_set1_ps(x); }
  static V load(const float* p) { return _mm_load_ps(p); }
  static V add(V a, V b) { return _mm_add_ps(a, b); }
  static V sub(V a, V b) { return _mm_sub_ps(a, b); }
  static V mul(V a, V b) { return _mm_mul_ps(a, b); }
  // a > b ? a : b and a < b ? a : b: b where either is NaN.
  static V max(V a, V b) { return _mm_max_ps(a, b); }
  static V min(V a, V b) { return _mm_min_ps(a, b); }
  static void store(float* p, V a) { _mm_storeu_ps(p, a); }
  // Bit k: a[k] <= b[k].
  static int le_mask(V a, V b) { return _mm_movemask_ps(_mm_cmple_ps(a, b)); }
};
#else
template <>
struct WideOps<4> {
  static constexpr bool kLanes = false;
  using V = float;
  static V set1(float x) { return x; }
};
#endif

// Which of node n's four boxes the ray meets for some t in [tmin, tmax]
// (bit k for child k), conservatively (WideRay); entry[k] is a lower bound
// of where it enters box k. A NaN slab distance (origin on a slab's plane,
// direction parallel to it) never moves the bounds, as in hit_box. The
// plain loop, for builds without SSE2; wide_hits_lanes does the same in
// one pass (bvh_walk.inc).
inline int wide_hits_scalar(const BvhWideNode& n, const WideRay& r, float tmin, float tmax,
                            float entry[4]) {
  int mask = 0;
  for (int k = 0; k < 4; ++k) {
    float lo = tmin, hi = tmax;
    for (int a = 0; a < 3; ++a) {
      const float tn = (n.planes[a][r.near_plane[a]][k] - r.origin[a]) * r.inv_near[a];
      const float tf = (n.planes[a][1 - r.near_plane[a]][k] - r.origin[a]) * r.inv_far[a];
      lo = tn > lo ? tn : lo;
      hi = tf < hi ? tf : hi;
    }
    lo = lo - r.slack;
    entry[k] = lo;
    if (lo <= hi) mask |= 1 << k;
  }
  return mask;
}

// The box test and the walk, once, compiled twice: here for the 4-wide
// tree, and below, in namespace avx2, as AVX2 code for the 8-wide one.
#include "common/geometry/bvh_walk.inc"

// Which of node n's four boxes the ray meets (wide_hits_scalar's answers,
// from its one pass where the build has SSE2).
inline int wide_hits(const BvhWideNode& n, const WideRay& r, float tmin, float tmax,
                     float entry[4]) {
  using O = WideOps<4>;
  return wide_hits_lanes<4>(n, WideRayLanes<4>(r), O::set1(tmin), O::set1(tmax), entry);
}

#if LOCUS_WIDE8
#pragma GCC push_options
#pragma GCC target("avx2")
// The 8-wide lanes: VMAXPS and VMINPS return the second operand on NaN, as
// MAXPS and MINPS do. No FMA: the target is AVX2 alone, so nothing here or
// inlined here is contracted, and every primitive test gives the 4-wide
// walk's answers bit for bit.
template <>
struct WideOps<8> {
  static constexpr bool kLanes = true;
  using V = __m256;
  static V set1(float x) { return _mm256_set1_ps(x); }
  static V load(const float* p) { return _mm256_load_ps(p); }
  static V add(V a, V b) { return _mm256_add_ps(a, b); }
  static V sub(V a, V b) { return _mm256_sub_ps(a, b); }
  static V mul(V a, V b) { return _mm256_mul_ps(a, b); }
  static V max(V a, V b) { return _mm256_max_ps(a, b); }
  static V min(V a, V b) { return _mm256_min_ps(a, b); }
  static void store(float* p, V a) { _mm256_storeu_ps(p, a); }
  static int le_mask(V a, V b) { return _mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ)); }
};
namespace avx2 {
#include "common/geometry/bvh_walk.inc"
// Out of line: a call from the callers' SSE2 code into AVX2 code.
template <bool kNearestFirst, typename F>
[[gnu::noinline]] void walk_wide8(const Bvh& bvh, const Ray& ray, double tmin, double tmax,
                                  F& visit) {
  avx2::walk_wide<8, kNearestFirst>(bvh.wide8.data(), bvh.order.data(), ray, tmin, tmax, visit);
}
}  // namespace avx2
// Which of an 8-wide node's boxes the ray meets (the walk keeps its bounds
// in lanes; tests call this one). AVX2 code: call it only where
// wide8_walk_available().
inline int wide_hits(const BvhWideNode8& n, const WideRay& r, float tmin, float tmax,
                     float entry[8]) {
  using O = WideOps<8>;
  return avx2::wide_hits_lanes<8>(n, avx2::WideRayLanes<8>(r), O::set1(tmin), O::set1(tmax), entry);
}
#pragma GCC pop_options
#endif

// The one ray walk, over the wide tree (the ray tracer's nearest hit and
// shadow rays, the shadow search's segments): visits the primitives of the
// leaves whose boxes the ray meets in [tmin, tmax] (conservatively: a leaf
// met only within the float test's slack may be visited too), the nearest
// box entered first. `visit(prim)` returns the possibly shortened tmax, or
// a negative value to stop the traversal; a pending box the ray enters
// beyond tmax is dropped. `visit(prim, slot)` may take the primitive's
// slot in bvh.order too (tables kept in leaf order: leaf_prims.h). With
// kNearestFirst false (a shadow ray, whose answer does not depend on the
// order it meets occluders in), the boxes met are taken in child order,
// without sorting them. The 8-wide tree is walked where it was built
// (Bvh::wide8), the 4-wide one otherwise; the primitives met are the same
// but for the float test's slack, and the walk's order may differ, which
// no caller's answer depends on (Tracer::nearest_by keeps coincident
// crossings by primitive, shadow crossings are sorted).
template <bool kNearestFirst = true, typename F>
void traverse_bvh(const Bvh& bvh, const Ray& ray, double tmin, double tmax, F&& visit) {
#if LOCUS_WIDE8
  if (!bvh.wide8.empty()) {
    avx2::walk_wide8<kNearestFirst>(bvh, ray, tmin, tmax, visit);
    return;
  }
#endif
  if (bvh.wide.empty()) return;
  walk_wide<4, kNearestFirst>(bvh.wide.data(), bvh.order.data(), ray, tmin, tmax, visit);
}

}  // namespace locus
