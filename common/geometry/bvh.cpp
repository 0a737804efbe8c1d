#include "common/geometry/bvh.h"

#include <algorithm>
#include <numeric>

namespace locus {
namespace {

constexpr int kBins = 16;
// Deeper nodes become leaves. A walk's stack then holds at most
// kMaxDepth + 1 entries (one pending sibling per level, and the two children
// of a node at depth kMaxDepth - 1): within walk_bvh's checked bound.
constexpr int kMaxDepth = 100;
static_assert(kMaxDepth + 1 <= kBvhWalkStack, "walk_bvh's stack must hold the deepest path");
constexpr int kLeafMax = 4;

struct BuildCtx {
  const std::vector<Aabb>& bounds;
  std::vector<Vec3> centres;
  Bvh& bvh;
};

int build_node(BuildCtx& ctx, int begin, int end, int depth) {
  const int id = static_cast<int>(ctx.bvh.nodes.size());
  ctx.bvh.nodes.emplace_back();
  Aabb box, cbox;
  for (int i = begin; i < end; ++i) {
    box.extend(ctx.bounds[ctx.bvh.order[i]]);
    cbox.extend(ctx.centres[ctx.bvh.order[i]]);
  }
  ctx.bvh.nodes[id].box = box;
  const int count = end - begin;
  auto make_leaf = [&] {
    ctx.bvh.nodes[id].first = begin;
    ctx.bvh.nodes[id].count = count;
    return id;
  };
  if (count <= 1 || depth >= kMaxDepth) return make_leaf();

  // Binned SAH over the axis of largest centroid extent.
  const Vec3 ext = cbox.hi - cbox.lo;
  const int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
  if (!(ext[axis] > 0)) {
    if (count <= kLeafMax) return make_leaf();
    // All centres coincide: split in the middle of the list.
    const int mid = begin + count / 2;
    build_node(ctx, begin, mid, depth + 1);
    ctx.bvh.nodes[id].first = build_node(ctx, mid, end, depth + 1);
    return id;
  }
  Aabb bin_box[kBins];
  int bin_count[kBins] = {};
  auto bin_of = [&](int prim) {
    return clamped_floor(kBins * (ctx.centres[prim][axis] - cbox.lo[axis]) / ext[axis], 0, kBins - 1);
  };
  for (int i = begin; i < end; ++i) {
    const int b = bin_of(ctx.bvh.order[i]);
    bin_box[b].extend(ctx.bounds[ctx.bvh.order[i]]);
    ++bin_count[b];
  }
  double left_area[kBins], right_area[kBins];
  int left_n[kBins], right_n[kBins];
  {
    Aabb acc;
    int n = 0;
    for (int b = 0; b < kBins; ++b) {
      acc.extend(bin_box[b]);
      n += bin_count[b];
      left_area[b] = acc.area();
      left_n[b] = n;
    }
    acc = Aabb();
    n = 0;
    for (int b = kBins - 1; b >= 0; --b) {
      acc.extend(bin_box[b]);
      n += bin_count[b];
      right_area[b] = acc.area();
      right_n[b] = n;
    }
  }
  int best = -1;
  double best_cost = 1e300;
  for (int b = 0; b + 1 < kBins; ++b) {
    if (left_n[b] == 0 || right_n[b + 1] == 0) continue;
    const double cost = left_area[b] * left_n[b] + right_area[b + 1] * right_n[b + 1];
    if (cost < best_cost) best_cost = cost, best = b;
  }
  const double leaf_cost = box.area() * count;
  // Traversal costs about one primitive test per node visited.
  if (best < 0 || (count <= kLeafMax && box.area() + best_cost >= leaf_cost)) return make_leaf();
  const auto mid_it = std::stable_partition(ctx.bvh.order.begin() + begin, ctx.bvh.order.begin() + end,
                                            [&](int prim) { return bin_of(prim) <= best; });
  const int mid = static_cast<int>(mid_it - ctx.bvh.order.begin());
  build_node(ctx, begin, mid, depth + 1);
  ctx.bvh.nodes[id].first = build_node(ctx, mid, end, depth + 1);
  return id;
}

}  // namespace

Bvh build_bvh(const std::vector<Aabb>& bounds) {
  Bvh bvh;
  if (bounds.empty()) return bvh;
  bvh.order.resize(bounds.size());
  std::iota(bvh.order.begin(), bvh.order.end(), 0);
  // Boxes grow by a relative 1e-9 of their coordinates: a ray lying exactly
  // in the plane of a flat primitive's box (a triangle of a mesh seen along
  // a shared edge) must not miss it by the last bit of the slab test's
  // rounding.
  std::vector<Aabb> padded(bounds);
  for (Aabb& b : padded) {
    if (b.empty()) continue;
    const double m = std::max(max_component(glm::abs(b.lo)), max_component(glm::abs(b.hi)));
    const Vec3 pad(1e-9 * m + 1e-300);
    b.lo -= pad;
    b.hi += pad;
  }
  BuildCtx ctx{padded, {}, bvh};
  ctx.centres.reserve(bounds.size());
  for (const Aabb& b : padded) ctx.centres.push_back(b.centre());
  bvh.nodes.reserve(2 * bounds.size());
  build_node(ctx, 0, static_cast<int>(bounds.size()), 0);
  return bvh;
}

}  // namespace locus
