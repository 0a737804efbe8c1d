// A bounding-volume hierarchy over primitive boxes, built with the surface
// area heuristic (binned). This is the "modern baseline" hierarchy used by
// --boxes eye+shadow in the ray tracer; the paper's own hierarchy of boxes
// (METHOD.md §7) builds on the same nodes.
#pragma once

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/geometry.h"

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

inline bool hit_box(const Aabb& b, const RayInv& r, double tmin, double tmax) {
  for (int a = 0; a < 3; ++a) {
    double t0 = (b.lo[a] - r.origin[a]) * r.inv[a];
    double t1 = (b.hi[a] - r.origin[a]) * r.inv[a];
    if (t0 > t1) std::swap(t0, t1);
    // A NaN (origin on a slab plane, direction parallel) must not cull.
    if (t0 > tmin) tmin = t0;
    if (t1 < tmax) tmax = t1;
    if (tmin > tmax) return false;
  }
  return true;
}

// Visits the primitives whose leaf boxes the ray meets in (tmin, tmax).
// `visit(prim)` returns the possibly shortened tmax, or a negative value to
// stop the traversal.
template <typename F>
void traverse_bvh(const Bvh& bvh, const Ray& ray, double tmin, double tmax, F&& visit) {
  if (bvh.nodes.empty()) return;
  const RayInv ri(ray);
  int stack[128];
  int sp = 0;
  stack[sp++] = 0;
  const bool neg[3] = {ray.dir.x < 0, ray.dir.y < 0, ray.dir.z < 0};
  while (sp) {
    const int ni = stack[--sp];
    const BvhNode& n = bvh.nodes[ni];
    if (!hit_box(n.box, ri, tmin, tmax)) continue;
    if (n.count > 0) {
      for (int i = n.first; i < n.first + n.count; ++i) {
        const double t = visit(bvh.order[i]);
        if (t < 0) return;
        tmax = t;
      }
    } else {
      // Push the far child first so the near one is visited first.
      const int left = ni + 1, right = n.first;
      const Vec3 d = bvh.nodes[right].box.centre() - bvh.nodes[left].box.centre();
      const int major = std::abs(d.x) > std::abs(d.y) ? (std::abs(d.x) > std::abs(d.z) ? 0 : 2)
                                                       : (std::abs(d.y) > std::abs(d.z) ? 1 : 2);
      const bool right_first = (d[major] < 0) != neg[major];
      if (right_first) {
        stack[sp++] = left;
        stack[sp++] = right;
      } else {
        stack[sp++] = right;
        stack[sp++] = left;
      }
    }
  }
}

}  // namespace locus
