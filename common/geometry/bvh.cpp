#include "common/geometry/bvh.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <string_view>

#include "common/base/parallel.h"

namespace locus {
namespace {

constexpr int kBins = 16;
// Deeper nodes become leaves. A walk's stack then holds at most
// kMaxDepth + 1 entries (one pending sibling per level, and the two children
// of a node at depth kMaxDepth - 1): within walk_bvh's checked bound.
constexpr int kMaxDepth = 100;
static_assert(kMaxDepth + 1 <= kBvhWalkStack, "walk_bvh's stack must hold the deepest path");
// A wide node's children lie at least one binary level below it, so the
// 4-wide tree is at most kMaxDepth + 1 levels deep, each leaving at most 3
// children pending in traverse_bvh.
static_assert(3 * (kMaxDepth + 1) <= kBvhRayStackN<4> && 7 * (kMaxDepth + 1) <= kBvhRayStackN<8>,
              "traverse_bvh's stack must hold the deepest path");
constexpr int kLeafMax = 4;

struct BuildCtx {
  const std::vector<Aabb>& bounds;
  std::vector<Vec3> centres;
  std::vector<int>& order;  // Bvh::order
};

// Whether the primitives [begin, end) of a node with box `box`, few enough
// for one leaf, cost less as a leaf each than as that one leaf, by the
// SAH's model (a node visited costs about one primitive test; a box is met
// in proportion to its area): a leaf each, under one 4-wide node whose
// boxes one SSE pass tests (traverse_bvh), costs the node and a test for
// each primitive whose own box the ray meets; the one leaf, a test of each
// wherever the ray meets `box`. The SAH's two-way split misses this where
// boxes overlap without filling each other: SPD jacks, whose cylinders
// cross at one centre (no plane separates them) and each fill a third of
// their common box, and whose balls sit at the cylinders' ends. There a
// leaf each halves the primitive tests (def jacks at 256x256, raytrace
// --spp 1: 66,125 -> 27,069; s2 jacks 199,974 -> 97,105) and takes 13-15%
// fewer instructions (callgrind), 6-25% less render CPU; images are
// bit-identical (Tracer::nearest_by's choice does not depend on the walk).
// Teapot, gears, lattice: 3-8% fewer tests, the same instructions to 1%.
bool leaf_each_pays(const BuildCtx& ctx, int begin, int end, const Aabb& box) {
  double own = 0;
  for (int i = begin; i < end; ++i) own += ctx.bounds[ctx.order[i]].area();
  return box.area() + own < box.area() * (end - begin);
}

// What the node of primitives [begin, end) becomes: a leaf, or an inner
// node whose children hold [begin, mid) and [mid, end) (the range is then
// partitioned so). `singles` (leaf_each_pays said so above): every
// primitive gets a leaf of its own; passed on to the children.
struct NodePlan {
  Aabb box;
  bool leaf = true;
  int mid = 0;
  bool singles = false;
};

NodePlan plan_node(const BuildCtx& ctx, int begin, int end, int depth, bool singles) {
  NodePlan plan;
  plan.singles = singles;
  Aabb cbox;
  for (int i = begin; i < end; ++i) {
    plan.box.extend(ctx.bounds[ctx.order[i]]);
    cbox.extend(ctx.centres[ctx.order[i]]);
  }
  const Aabb& box = plan.box;
  const int count = end - begin;
  if (count <= 1 || depth >= kMaxDepth) return plan;

  // The axis of largest centre extent: none if the centres coincide.
  const Vec3 ext = cbox.hi - cbox.lo;
  const int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
  if (!(ext[axis] > 0)) {
    // All centres coincide (concentric bodies: SPD jacks' three
    // cylinders), so no plane separates them: a few are one leaf unless a
    // leaf each pays (leaf_each_pays).
    if (!singles && count <= kLeafMax) {
      if (!leaf_each_pays(ctx, begin, end, box)) return plan;
      plan.singles = true;
    }
    // Split in the middle of the list.
    plan.leaf = false;
    plan.mid = begin + count / 2;
    return plan;
  }
  // Binned SAH on each axis the centres spread along (kBins bins of
  // centre position per axis, one pass over the primitives): the cheapest
  // split of the three. On the largest axis alone (as before session 28)
  // the ray walk met 10-13% more nodes and made 4-6% more primitive tests
  // on SPD teapot, balls and rings; with all three, 2-9% less render CPU
  // (raytrace --spp 1, 512x512) for a build about 1.4x as long (tetra
  // level 9's prepare 0.18 -> 0.22 s; docs/renderer.md, "Session 28").
  auto bin_of = [&](int prim, int a) {
    return clamped_floor(kBins * (ctx.centres[prim][a] - cbox.lo[a]) / ext[a], 0, kBins - 1);
  };
  Aabb bin_box[3][kBins];
  int bin_count[3][kBins] = {};
  for (int i = begin; i < end; ++i) {
    const int prim = ctx.order[i];
    for (int a = 0; a < 3; ++a) {
      if (!(ext[a] > 0)) continue;
      const int b = bin_of(prim, a);
      bin_box[a][b].extend(ctx.bounds[prim]);
      ++bin_count[a][b];
    }
  }
  int best = -1, best_axis = axis;
  double best_cost = 1e300;
  for (int a = 0; a < 3; ++a) {
    if (!(ext[a] > 0)) continue;
    double right_area[kBins];
    int right_n[kBins];
    Aabb acc;
    int n = 0;
    for (int b = kBins - 1; b >= 0; --b) {
      acc.extend(bin_box[a][b]);
      n += bin_count[a][b];
      right_area[b] = acc.area();
      right_n[b] = n;
    }
    acc = Aabb();
    n = 0;
    for (int b = 0; b + 1 < kBins; ++b) {
      acc.extend(bin_box[a][b]);
      n += bin_count[a][b];
      if (n == 0 || right_n[b + 1] == 0) continue;
      const double cost = acc.area() * n + right_area[b + 1] * right_n[b + 1];
      if (cost < best_cost) best_cost = cost, best = b, best_axis = a;
    }
  }
  const double leaf_cost = box.area() * count;
  // Traversal costs about one primitive test per node visited.
  if (best < 0) return plan;
  if (!singles && count <= kLeafMax && box.area() + best_cost >= leaf_cost) {
    if (!leaf_each_pays(ctx, begin, end, box)) return plan;
    plan.singles = true;
  }
  const auto mid_it =
      std::stable_partition(ctx.order.begin() + begin, ctx.order.begin() + end,
                            [&](int prim) { return bin_of(prim, best_axis) <= best; });
  plan.leaf = false;
  plan.mid = static_cast<int>(mid_it - ctx.order.begin());
  return plan;
}

// A subtree left for a thread of its own (build_parallel).
struct Subtree {
  int begin, end, depth;
  bool singles;
  std::vector<BvhNode> nodes;  // its own indices, its root at 0
};

// Where build_node leaves subtrees of at most `cut` primitives for later:
// each a placeholder node (count -1 - its index in `subtrees`).
struct Deferred {
  int cut;
  std::vector<Subtree>& subtrees;
};

// Builds the subtree of primitives [begin, end) into `nodes` (depth first:
// a node, its left subtree, its right subtree); returns its root's index.
// With `defer`, only the top of it (build_parallel).
int build_node(const BuildCtx& ctx, std::vector<BvhNode>& nodes, int begin, int end, int depth,
               bool singles, Deferred* defer = nullptr) {
  const int id = static_cast<int>(nodes.size());
  nodes.emplace_back();
  if (defer && end - begin <= defer->cut) {
    nodes[id].count = -1 - static_cast<int>(defer->subtrees.size());
    defer->subtrees.push_back(Subtree{begin, end, depth, singles, {}});
    return id;
  }
  const NodePlan plan = plan_node(ctx, begin, end, depth, singles);
  nodes[id].box = plan.box;
  if (plan.leaf) {
    nodes[id].first = begin;
    nodes[id].count = end - begin;
    return id;
  }
  build_node(ctx, nodes, begin, plan.mid, depth + 1, plan.singles, defer);
  nodes[id].first = build_node(ctx, nodes, plan.mid, end, depth + 1, plan.singles, defer);
  return id;
}

// Node `id` of the top and everything below it into `out`, depth first as
// build_node lays them out; returns its index there.
int splice(const std::vector<BvhNode>& top, std::vector<Subtree>& subtrees, int id,
           std::vector<BvhNode>& out) {
  const BvhNode& n = top[id];
  const int at = static_cast<int>(out.size());
  if (n.count < 0) {
    for (BvhNode m : subtrees[-1 - n.count].nodes) {
      if (m.count == 0) m.first += at;  // an inner node's right child
      out.push_back(m);
    }
    return at;
  }
  out.push_back(n);
  if (n.count > 0) return at;
  splice(top, subtrees, id + 1, out);
  out[at].first = splice(top, subtrees, n.first, out);
  return at;
}

// Fewer primitives than this are built on one thread.
constexpr int kParallelPrims = 16384;

// The tree of build_node, node for node, on `threads` threads: its top on
// this one, down to subtrees of at most an eighth of the primitives a
// thread, those side by side (each owns its range of Bvh::order), then
// joined in place.
void build_parallel(const BuildCtx& ctx, std::vector<BvhNode>& nodes, int n, int threads) {
  std::vector<BvhNode> top;
  std::vector<Subtree> subtrees;
  Deferred defer{std::max(1, n / (8 * threads)), subtrees};
  build_node(ctx, top, 0, n, 0, false, &defer);
  parallel_for(static_cast<int>(subtrees.size()), threads, [&](int i) {
    Subtree& t = subtrees[i];
    t.nodes.reserve(2 * (t.end - t.begin));
    build_node(ctx, t.nodes, t.begin, t.end, t.depth, t.singles);
  });
  splice(top, subtrees, 0, nodes);
}

// A wide node of empty slots (lo = +inf, hi = -inf: no ray meets them).
template <int W>
BvhWideNodeN<W> empty_wide_node() {
  BvhWideNodeN<W> w;
  for (int k = 0; k < W; ++k) {
    for (int a = 0; a < 3; ++a) {
      w.planes[a][0][k] = std::numeric_limits<float>::infinity();
      w.planes[a][1][k] = -std::numeric_limits<float>::infinity();
    }
    w.ref[k] = 0;
    w.count[k] = -1;
  }
  return w;
}

// Child slot k: `box` rounded outward to float, and the child.
template <int W>
void set_slot(BvhWideNodeN<W>& w, int k, const Aabb& box, int ref, int count) {
  for (int a = 0; a < 3; ++a) {
    w.planes[a][0][k] = float_down(box.lo[a]);
    w.planes[a][1][k] = float_up(box.hi[a]);
  }
  w.ref[k] = ref;
  w.count[k] = count;
}

// Collapses binary inner node ni into a wide node of `out`: its children,
// the inner child of largest area replaced by its two children while there
// are fewer than W. Returns the wide node's index.
template <int W>
int collapse(const Bvh& bvh, std::vector<BvhWideNodeN<W>>& out, int ni) {
  int child[W] = {ni + 1, bvh.nodes[ni].first};
  int n = 2;
  while (n < W) {
    int widest = -1;
    double widest_area = -1.0;
    for (int k = 0; k < n; ++k) {
      const BvhNode& c = bvh.nodes[child[k]];
      if (c.count == 0 && c.box.area() > widest_area) widest = k, widest_area = c.box.area();
    }
    if (widest < 0) break;
    const int w = child[widest];
    child[widest] = w + 1;
    child[n++] = bvh.nodes[w].first;
  }
  const int id = static_cast<int>(out.size());
  out.push_back(empty_wide_node<W>());
  for (int k = 0; k < n; ++k) {
    const BvhNode& c = bvh.nodes[child[k]];
    const int ref = c.count > 0 ? c.first : collapse(bvh, out, child[k]);  // may move out
    set_slot(out[id], k, c.box, ref, c.count);
  }
  return id;
}

template <int W>
void build_wide_n(const Bvh& bvh, std::vector<BvhWideNodeN<W>>& out) {
  out.clear();
  if (bvh.nodes.empty()) return;
  const BvhNode& root = bvh.nodes[0];
  if (root.count > 0) {
    // A root leaf: one wide node holding it.
    out.push_back(empty_wide_node<W>());
    set_slot(out[0], 0, root.box, root.first, root.count);
    return;
  }
  out.reserve(bvh.nodes.size() / (W / 2) + 1);
  collapse(bvh, out, 0);
}

}  // namespace

void build_wide(Bvh& bvh) { build_wide_n(bvh, bvh.wide); }

void build_wide8(Bvh& bvh) { build_wide_n(bvh, bvh.wide8); }

bool wide8_walk_available() {
#if LOCUS_WIDE8
  // LOCUS_KERNEL_WIDTH=4 keeps the 4-wide walk (to measure the two side by
  // side in one binary).
  static const bool yes = [] {
    const char* w = std::getenv("LOCUS_KERNEL_WIDTH");
    if (w && std::string_view(w) == "4") return false;
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return yes;
#else
  return false;
#endif
}

Bvh build_bvh(const std::vector<Aabb>& bounds, int threads) {
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
  BuildCtx ctx{padded, {}, bvh.order};
  ctx.centres.reserve(bounds.size());
  for (const Aabb& b : padded) ctx.centres.push_back(b.centre());
  const int n = static_cast<int>(bounds.size());
  bvh.nodes.reserve(2 * bounds.size());
  if (threads > 1 && n >= kParallelPrims) {
    build_parallel(ctx, bvh.nodes, n, threads);
  } else {
    build_node(ctx, bvh.nodes, 0, n, 0, false);
  }
  // Only the walk traverse_bvh takes: the other would cost the frame's
  // preparation its collapse and its memory for nothing.
  if (wide8_walk_available()) {
    build_wide8(bvh);
  } else {
    build_wide(bvh);
  }
  return bvh;
}

}  // namespace locus
