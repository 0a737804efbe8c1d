// The hierarchy's walks: the ray walk (traverse_bvh, over the 4-wide float
// tree, and over the 8-wide one where the processor has AVX2) visits every
// leaf a brute-force double box test gives and only leaves within the float
// test's slack besides; the 4-wide and 8-wide box tests never miss a box
// the double slab test meets (slab planes, parallel rays, far origins);
// the region walk (walk_bvh) visits exactly the leaves its node
// test accepts; a hierarchy deeper than a walk's stack trips the
// LOCUS_CHECK instead of writing past the array. The builder gives
// primitives a leaf each where their own boxes are small against the
// leaf's (leaf_each_pays).
#include "common/geometry/bvh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace locus {
namespace {

constexpr int kBoxes = 400;
constexpr int kRays = 2000;

std::vector<Aabb> random_boxes(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> pos(-1, 1), size(0.001, 0.15);
  std::vector<Aabb> boxes;
  for (int i = 0; i < kBoxes; ++i) {
    const Vec3 c(pos(rng), pos(rng), pos(rng));
    const Vec3 h(size(rng), size(rng), size(rng));
    Aabb b;
    b.extend(c - h);
    b.extend(c + h);
    boxes.push_back(b);
  }
  return boxes;
}

// From a random point on a sphere of radius 3, towards a random point of
// [-1, 1]^3, with a random end.
struct TestRay {
  Ray ray;
  double tmax;
};
TestRay random_ray(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1), end(0.5, 8);
  std::normal_distribution<double> g;
  Vec3 o(g(rng), g(rng), g(rng));
  o = 3.0 * o / glm::length(o);
  const Vec3 target(u(rng), u(rng), u(rng));
  return TestRay{Ray{o, glm::normalize(target - o)}, end(rng)};
}

// The primitives the ray walk visits for r, in the order it visits them.
std::vector<int> visited_by(const Bvh& bvh, const TestRay& r) {
  std::vector<int> visited;
  traverse_bvh(bvh, r.ray, 0.0, r.tmax, [&](int prim) {
    visited.push_back(prim);
    return r.tmax;
  });
  return visited;
}

// The primitives of the leaves that `leaf_meets(box)` accepts, sorted.
template <class Meets>
std::vector<int> brute_force_leaves(const Bvh& bvh, Meets&& leaf_meets) {
  std::vector<int> out;
  for (const BvhNode& n : bvh.nodes) {
    if (n.count == 0 || !leaf_meets(n.box)) continue;
    for (int i = n.first; i < n.first + n.count; ++i) out.push_back(bvh.order[i]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Box b grown by `rel` of its size and coordinates.
Aabb grown(const Aabb& b, double rel) {
  const double m = std::max(max_component(glm::abs(b.lo)), max_component(glm::abs(b.hi)));
  const Vec3 pad((b.hi - b.lo) * rel + Vec3(m * rel));
  return Aabb{b.lo - pad, b.hi + pad};
}

// The two ray walks of one hierarchy: the 4-wide one, and the 8-wide one
// where this processor has AVX2 (where it has not, build_bvh made none).
std::vector<Bvh> both_walks(const Bvh& built) {
  Bvh four = built;
  four.wide8.clear();
  build_wide(four);
  std::vector<Bvh> out = {four};
  if (wide8_walk_available()) {
    EXPECT_FALSE(built.wide8.empty());
    out.push_back(built);
  } else {
    EXPECT_TRUE(built.wide8.empty());
  }
  return out;
}

// Whether the AVX2 walk runs here: on x86-64, it must (LOCUS_KERNEL_WIDTH=4
// turns it off).
TEST(BvhWalk, EightWideWalkRunsWhereTheProcessorHasAvx2) {
#if LOCUS_WIDE8
  const char* w = std::getenv("LOCUS_KERNEL_WIDTH");
  const bool off = w && std::string(w) == "4";
  EXPECT_EQ(wide8_walk_available(), !off && __builtin_cpu_supports("avx2"));
#else
  EXPECT_FALSE(wide8_walk_available());
#endif
  // build_bvh makes the one form traverse_bvh walks.
  std::mt19937_64 rng(5);
  const Bvh bvh = build_bvh(random_boxes(rng));
  EXPECT_EQ(bvh.wide8.empty(), !wide8_walk_available());
  EXPECT_EQ(bvh.wide.empty(), wide8_walk_available());
}

TEST(BvhWalk, TraversalVisitsTheLeavesTheRayMeets) {
  const uint64_t seed = 22;
  std::mt19937_64 rng(seed);
  const std::vector<Aabb> boxes = random_boxes(rng);
  for (const Bvh& bvh : both_walks(build_bvh(boxes))) {
    const int width = bvh.wide8.empty() ? 4 : 8;
    int extra = 0, total = 0;
    for (int k = 0; k < kRays; ++k) {
      const TestRay r = random_ray(rng);
      const RayInv ri(r.ray);
      std::vector<int> visited = visited_by(bvh, r);
      std::sort(visited.begin(), visited.end());
      ASSERT_TRUE(std::adjacent_find(visited.begin(), visited.end()) == visited.end())
          << "a primitive visited twice, seed " << seed << ", ray " << k << ", width " << width;
      // Every leaf the double test meets is visited ...
      const std::vector<int> met = brute_force_leaves(
          bvh, [&](const Aabb& b) { return hit_box_scalar(b, ri, 0.0, r.tmax); });
      ASSERT_TRUE(std::includes(visited.begin(), visited.end(), met.begin(), met.end()))
          << "seed " << seed << ", ray " << k << ", width " << width;
      // ... and besides them only leaves the ray passes within the float
      // test's slack of.
      const std::vector<int> near = brute_force_leaves(bvh, [&](const Aabb& b) {
        return hit_box_scalar(grown(b, 1e-5), ri, -1e-5 * r.tmax, r.tmax * (1 + 1e-5));
      });
      ASSERT_TRUE(std::includes(near.begin(), near.end(), visited.begin(), visited.end()))
          << "seed " << seed << ", ray " << k << ", width " << width;
      extra += static_cast<int>(visited.size() - met.size());
      total += static_cast<int>(visited.size());
      // Conservative: every primitive whose own box the ray meets is visited.
      for (int p = 0; p < kBoxes; ++p) {
        if (hit_box_scalar(boxes[p], ri, 0.0, r.tmax)) {
          ASSERT_TRUE(std::binary_search(visited.begin(), visited.end(), p))
              << "seed " << seed << ", ray " << k << ", box " << p << ", width " << width;
        }
      }
    }
    EXPECT_GT(total, kRays);
    EXPECT_LT(extra, total / 1000 + 1) << "width " << width;
  }
}

// The nearest box first: a walk that shortens tmax to each primitive's box
// entry (as a nearest-hit search does) ends with the same nearest entry in
// both walks, having visited only primitives whose boxes the ray meets
// before it.
TEST(BvhWalk, BothWalksFindTheSameNearestBox) {
  std::mt19937_64 rng(31);
  const std::vector<Aabb> boxes = random_boxes(rng);
  const std::vector<Bvh> walks = both_walks(build_bvh(boxes));
  int found = 0;
  for (int k = 0; k < kRays; ++k) {
    const TestRay r = random_ray(rng);
    const RayInv ri(r.ray);
    std::vector<double> nearest;
    for (const Bvh& bvh : walks) {
      double best = r.tmax;
      traverse_bvh(bvh, r.ray, 0.0, r.tmax, [&](int prim) {
        if (hit_box_scalar(boxes[prim], ri, 0.0, best))
          best = std::min(best, box_entry(boxes[prim], ri, 0.0));
        return best;
      });
      nearest.push_back(best);
    }
    for (double t : nearest) ASSERT_EQ(t, nearest[0]) << "ray " << k;
    found += nearest[0] < r.tmax;
  }
  EXPECT_GT(found, kRays / 4);
}

// The 4-wide float box test against the double slab loop: a box the double
// test meets is met, and entered no later than it says (and the 8-wide
// test answers as the 4-wide one does, bit for bit), on random boxes and
// rays and on rays whose origin lies on a slab's plane with a direction
// component of +0 or -0 (NaN slab distances), on a box's face or edge, far
// from the origin (the float origin's rounding), with tmax at the entry.
TEST(BvhWalk, WideBoxTestNeverMissesWhatTheDoubleTestMeets) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2.0, 2.0), unit(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 5);
  const double grid[] = {-1.0, -0.5, 0.0, 0.5, 1.0};
  const double offsets[] = {0.0, 0.1, 1e3 / 3, -7e5 / 3};
  int hits = 0, misses = 0, eight_wide = 0;
  for (int k = 0; k < 100000; ++k) {
    const Vec3 shift(offsets[k % 4], offsets[(k / 4) % 4], offsets[(k / 16) % 4]);
    BvhWideNode n;
    Aabb box[4];
    for (int c = 0; c < 4; ++c) {
      box[c].extend(shift + Vec3(grid[pick(rng) % 5], grid[pick(rng) % 5], grid[pick(rng) % 5]));
      box[c].extend(shift + Vec3(grid[pick(rng) % 5], grid[pick(rng) % 5], grid[pick(rng) % 5]));
      for (int a = 0; a < 3; ++a) {
        n.planes[a][0][c] = float_down(box[c].lo[a]);
        n.planes[a][1][c] = float_up(box[c].hi[a]);
      }
    }
    Vec3 o(u(rng), u(rng), u(rng)), d(u(rng), u(rng), u(rng));
    for (int a = 0; a < 3; ++a) {
      switch (pick(rng)) {
        case 0: d[a] = 0.0; break;
        case 1: d[a] = -0.0; break;
        case 2: o[a] = grid[pick(rng) % 5] + unit(rng) * 1e-12; break;  // on or near a plane
        case 3: o[a] = grid[pick(rng) % 5]; d[a] = pick(rng) % 2 ? 0.0 : -0.0; break;
        default: break;
      }
    }
    o += shift;
    const Ray ray{o, d};
    const RayInv ri(ray);
    const WideRay wr(ray);
    const double tmin = pick(rng) % 2 ? 0.0 : unit(rng);
    const double tmax = pick(rng) % 3 == 0 ? box_entry(box[k % 4], ri, tmin) : 1e300;
    float entry[4];
    const int mask = wide_hits(n, wr, float_down(tmin), float_up(tmax), entry);
#if LOCUS_WIDE8
    // The 8-wide test, with the four boxes in slots 0-3 and again,
    // reversed, in slots 4-7: the same answers in both places.
    if (wide8_walk_available()) {
      BvhWideNode8 n8;
      for (int c = 0; c < 8; ++c) {
        for (int a = 0; a < 3; ++a) {
          for (int side = 0; side < 2; ++side)
            n8.planes[a][side][c] = n.planes[a][side][c < 4 ? c : 7 - c];
        }
      }
      float entry8[8];
      const int mask8 = wide_hits(n8, wr, float_down(tmin), float_up(tmax), entry8);
      for (int c = 0; c < 4; ++c) {
        ASSERT_EQ((mask8 >> c) & 1, (mask >> c) & 1) << "ray " << k << ", box " << c;
        ASSERT_EQ((mask8 >> (7 - c)) & 1, (mask >> c) & 1) << "ray " << k << ", box " << c;
        if ((mask >> c) & 1) {
          ASSERT_EQ(entry8[c], entry[c]) << "ray " << k << ", box " << c;
          ASSERT_EQ(entry8[7 - c], entry[c]) << "ray " << k << ", box " << c;
        }
      }
      ++eight_wide;
    }
#endif
    for (int c = 0; c < 4; ++c) {
      // (An entry at infinity, from a zero direction, is no point of the ray.)
      const bool want =
          hit_box_scalar(box[c], ri, tmin, tmax) && std::isfinite(box_entry(box[c], ri, tmin));
      const bool got = (mask >> c) & 1;
      ASSERT_TRUE(got || !want) << "ray " << k << ", box " << c << ": (" << box[c].lo.x << ", "
                                << box[c].lo.y << ", " << box[c].lo.z << ")-(" << box[c].hi.x
                                << ", " << box[c].hi.y << ", " << box[c].hi.z << ") origin ("
                                << o.x << ", " << o.y << ", " << o.z << ") direction (" << d.x
                                << ", " << d.y << ", " << d.z << ")";
      if (want) {
        ASSERT_LE(entry[c], box_entry(box[c], ri, tmin)) << "ray " << k << ", box " << c;
        ++hits;
      } else if (!got) {
        ++misses;
      }
    }
  }
  // Both outcomes are well represented; the rays near slab planes make
  // the float test take many near misses (how tight it is on ordinary rays:
  // TraversalVisitsTheLeavesTheRayMeets).
  EXPECT_GT(hits, 10000);
  EXPECT_GT(misses, 100000);
  EXPECT_EQ(eight_wide, wide8_walk_available() ? 100000 : 0);
}

// float_down and float_up, inline by the float's bits, give what the
// definition by std::nextafter gives: the nearest float on the safe side.
TEST(BvhWalk, FloatBoundsAreTheNearestFloatsOnTheirSide) {
  const float inf = std::numeric_limits<float>::infinity();
  auto down = [&](double x) {
    const float f = static_cast<float>(x);
    return static_cast<double>(f) > x ? std::nextafter(f, -inf) : f;
  };
  auto up = [&](double x) {
    const float f = static_cast<float>(x);
    return static_cast<double>(f) < x ? std::nextafter(f, inf) : f;
  };
  std::vector<double> xs = {0.0, -0.0, 1.0, -1.0, 0.1, -0.1, 1e-45, -1e-45, 1e-300, -1e-300,
                            3.4028234663852886e38, 3.4028235677973366e38, -3.4028235677973366e38,
                            1e39, -1e39, std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity(),
                            static_cast<double>(std::numeric_limits<float>::denorm_min()) * 0.5,
                            -static_cast<double>(std::numeric_limits<float>::denorm_min()) * 1.5};
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> ex(-160, 140);
  for (int i = 0; i < 20000; ++i) xs.push_back(std::ldexp(mant(rng), ex(rng)));
  for (const double x : xs) {
    const float d = float_down(x), u = float_up(x);
    EXPECT_EQ(std::bit_cast<uint32_t>(d), std::bit_cast<uint32_t>(down(x))) << x;
    EXPECT_EQ(std::bit_cast<uint32_t>(u), std::bit_cast<uint32_t>(up(x))) << x;
    EXPECT_LE(static_cast<double>(d), x) << x;
    EXPECT_GE(static_cast<double>(u), x) << x;
  }
  EXPECT_TRUE(std::isnan(float_down(std::nan(""))));
  EXPECT_TRUE(std::isnan(float_up(std::nan(""))));
}

// The span shadows' use: another node test (here a query box against the
// nodes' boxes), the left child first.
TEST(BvhWalk, WalkWithAnotherNodeTestVisitsExactlyTheLeavesItAccepts) {
  const uint64_t seed = 2022;
  std::mt19937_64 rng(seed);
  const Bvh bvh = build_bvh(random_boxes(rng));
  std::uniform_real_distribution<double> pos(-1.2, 1.2), size(0.0, 0.5);
  for (int k = 0; k < kRays; ++k) {
    const Vec3 c(pos(rng), pos(rng), pos(rng));
    const Vec3 h(size(rng), size(rng), size(rng));
    const Vec3 lo = c - h, hi = c + h;
    auto overlaps = [&](const Aabb& b) {
      return b.lo.x <= hi.x && lo.x <= b.hi.x && b.lo.y <= hi.y && lo.y <= b.hi.y &&
             b.lo.z <= hi.z && lo.z <= b.hi.z;
    };
    std::vector<int> visited;
    const bool finished = walk_bvh(
        bvh, [&](int ni) { return overlaps(bvh.nodes[ni].box); },
        [&](int prim) {
          visited.push_back(prim);
          return true;
        });
    EXPECT_TRUE(finished);
    std::sort(visited.begin(), visited.end());
    ASSERT_EQ(visited, brute_force_leaves(bvh, overlaps)) << "seed " << seed << ", box " << k;
  }
}

TEST(BvhWalk, VisitEndsTheWalk) {
  std::mt19937_64 rng(7);
  const Bvh bvh = build_bvh(random_boxes(rng));
  int visits = 0;
  const bool finished = walk_bvh(
      bvh, [](int) { return true; },
      [&](int) {
        ++visits;
        return false;
      });
  EXPECT_FALSE(finished);
  EXPECT_EQ(visits, 1);
  visits = 0;
  traverse_bvh(bvh, Ray{Vec3(-3, 0, 0), Vec3(1, 0, 0)}, 0.0, 10.0, [&](int) {
    ++visits;
    return -1.0;
  });
  EXPECT_LE(visits, 1);
}

// The deepest hierarchies build_bvh makes (cubes shrinking geometrically
// towards the origin, so the SAH peels off a few at a time down to its
// depth limit) stay within the walk's stack.
TEST(BvhWalk, DeepestBuiltHierarchyFitsTheStack) {
  std::vector<Aabb> boxes;
  double x = 1.0;
  for (int i = 0; i < 600; ++i, x *= 0.5) {
    Aabb b;
    b.extend(Vec3(x));
    b.extend(Vec3(1.1 * x));
    boxes.push_back(b);
  }
  const Bvh bvh = build_bvh(boxes);
  // The hierarchy's depth (children follow their parent in `nodes`).
  std::vector<int> depth(bvh.nodes.size(), 0);
  int deepest = 0;
  for (size_t ni = 0; ni < bvh.nodes.size(); ++ni) {
    deepest = std::max(deepest, depth[ni]);
    const BvhNode& n = bvh.nodes[ni];
    if (n.count == 0) depth[ni + 1] = depth[n.first] = depth[ni] + 1;
  }
  EXPECT_GT(deepest, 64) << "the boxes no longer build a deep hierarchy";
  EXPECT_LT(deepest + 1, kBvhWalkStack);
  std::vector<int> visited;
  traverse_bvh(bvh, Ray{Vec3(-1.0), glm::normalize(Vec3(1.0))}, 0.0, 10.0, [&](int prim) {
    visited.push_back(prim);
    return 10.0;
  });
  EXPECT_EQ(visited.size(), boxes.size());
}

// A chain of inner nodes built by hand, deeper than the stack: node i's
// left child is node i + 1, its right child one shared leaf. Walked left
// first, every level leaves a right child pending.
Bvh degenerate_chain(int depth) {
  Bvh bvh;
  Aabb box;
  box.extend(Vec3(-1.0));
  box.extend(Vec3(1.0));
  for (int i = 0; i < depth; ++i) bvh.nodes.push_back(BvhNode{box, depth + 1, 0});
  bvh.nodes.push_back(BvhNode{box, 0, 1});  // the chain's last left child
  bvh.nodes.push_back(BvhNode{box, 0, 1});  // every right child
  bvh.order = {0};
  build_wide(bvh);
  return bvh;
}

// The same, walked 8-wide.
Bvh degenerate_chain8(int depth) {
  Bvh bvh = degenerate_chain(depth);
  build_wide8(bvh);
  return bvh;
}

TEST(BvhWalkDeathTest, DeeperThanTheStackTripsTheCheck) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const Bvh bvh = degenerate_chain(kBvhWalkStack);
  EXPECT_DEATH(walk_bvh(
                   bvh, [](int) { return true; }, [](int) { return true; }),
               "CHECK failed: sp \\+ 2 <= kBvhWalkStack");
  // The 4-wide form of a chain 3 levels deeper than kBvhRayStack: each wide
  // node holds 3 leaves and the rest of the chain, all at the same entry
  // distance, and the chain goes first.
  EXPECT_DEATH(
      traverse_bvh(degenerate_chain(kBvhRayStack + 3), Ray{Vec3(0.1, 0.2, -5), Vec3(0, 0, 1)}, 0.0,
                   10.0, [](int) { return 10.0; }),
      "CHECK failed: sp \\+ \\(W - 1\\) <= kBvhRayStackN<W>");
  // The 8-wide form of a chain 14 levels deeper than its stack: each wide
  // node holds 7 leaves and the rest of the chain.
  if (wide8_walk_available()) {
    EXPECT_DEATH(
        traverse_bvh(degenerate_chain8(kBvhRayStackN<8> + 14),
                     Ray{Vec3(0.1, 0.2, -5), Vec3(0, 0, 1)}, 0.0, 10.0, [](int) { return 10.0; }),
        "CHECK failed: sp \\+ \\(W - 1\\) <= kBvhRayStackN<W>");
  }
  // One level less is the longest chain the stack holds: walked to the end,
  // each right child and the last left one visited.
  int visits = 0;
  walk_bvh(
      degenerate_chain(kBvhWalkStack - 1), [](int) { return true; },
      [&](int) {
        ++visits;
        return true;
      });
  EXPECT_EQ(visits, kBvhWalkStack);
}

// The leaves that hold primitive p: how many primitives share its leaf.
int leaf_size_of(const Bvh& bvh, int p) {
  for (const BvhNode& n : bvh.nodes) {
    if (n.count == 0) continue;
    for (int i = n.first; i < n.first + n.count; ++i)
      if (bvh.order[i] == p) return n.count;
  }
  return 0;
}

Aabb box_of(const Vec3& lo, const Vec3& hi) {
  Aabb b;
  b.extend(lo);
  b.extend(hi);
  return b;
}

TEST(BvhBuild, ALeafEachWhereTheirOwnBoxesAreSmallerThanTheirs) {
  // Three thin rods crossing at the origin (SPD jacks' cylinders): their
  // centres coincide, and each box is a sliver of their common box.
  const std::vector<Aabb> rods = {box_of(Vec3(-1, -0.05, -0.05), Vec3(1, 0.05, 0.05)),
                                  box_of(Vec3(-0.05, -1, -0.05), Vec3(0.05, 1, 0.05)),
                                  box_of(Vec3(-0.05, -0.05, -1), Vec3(0.05, 0.05, 1))};
  const Bvh crossed = build_bvh(rods);
  for (int p = 0; p < 3; ++p) EXPECT_EQ(leaf_size_of(crossed, p), 1) << "rod " << p;
  // Three nested boxes about one centre (concentric shells): each fills
  // most of the next, so a leaf each would cost more: one leaf.
  const std::vector<Aabb> nested = {box_of(Vec3(-1), Vec3(1)), box_of(Vec3(-0.9), Vec3(0.9)),
                                    box_of(Vec3(-0.95), Vec3(0.95))};
  const Bvh shells = build_bvh(nested);
  for (int p = 0; p < 3; ++p) EXPECT_EQ(leaf_size_of(shells, p), 3) << "shell " << p;
  // Centres apart: a large box and two small ones inside it at opposite
  // corners (a jack's cylinder and its balls). Any two-way split leaves
  // one side as large as the whole, so the SAH keeps them one leaf; a leaf
  // each costs less, the small ones being met a fraction as often.
  const std::vector<Aabb> mixed = {box_of(Vec3(-1), Vec3(1)), box_of(Vec3(0.8), Vec3(0.9)),
                                   box_of(Vec3(-0.9), Vec3(-0.8))};
  const Bvh split = build_bvh(mixed);
  for (int p = 0; p < 3; ++p) EXPECT_EQ(leaf_size_of(split, p), 1) << "box " << p;
  // Every ray still meets each primitive it met (the walk is conservative).
  std::mt19937_64 rng(7);
  for (const auto* set : {&rods, &nested, &mixed}) {
    const Bvh bvh = build_bvh(*set);
    for (int k = 0; k < 500; ++k) {
      const TestRay r = random_ray(rng);
      const RayInv ri(r.ray);
      const std::vector<int> visited = visited_by(bvh, r);
      for (int p = 0; p < static_cast<int>(set->size()); ++p) {
        if (hit_box_scalar((*set)[p], ri, 0.0, r.tmax)) {
          EXPECT_NE(std::find(visited.begin(), visited.end(), p), visited.end()) << "ray " << k;
        }
      }
    }
  }
}

// The wide nodes of two trees, slot for slot.
template <int W>
void expect_same_wide(const std::vector<BvhWideNodeN<W>>& a, const std::vector<BvhWideNodeN<W>>& b,
                      int threads) {
  ASSERT_EQ(a.size(), b.size()) << threads << " threads";
  for (size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < W; ++k) {
      ASSERT_EQ(a[i].ref[k], b[i].ref[k]) << "wide node " << i << ", " << threads << " threads";
      ASSERT_EQ(a[i].count[k], b[i].count[k]) << "wide node " << i << ", " << threads << " threads";
      for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
          ASSERT_EQ(std::bit_cast<uint32_t>(a[i].planes[axis][side][k]),
                    std::bit_cast<uint32_t>(b[i].planes[axis][side][k]))
              << "wide node " << i << ", " << threads << " threads";
        }
      }
    }
  }
}

TEST(BvhBuild, TheSameTreeOnAnyNumberOfThreads) {
  // Enough primitives for the subtrees to be built side by side: random
  // boxes, and among them runs whose centres coincide (a leaf each, or a
  // split in the middle of the list) and duplicates.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> pos(-1, 1), size(0.0001, 0.02);
  std::vector<Aabb> boxes;
  while (boxes.size() < 60000) {
    const Vec3 c(pos(rng), pos(rng), pos(rng));
    const Vec3 h(size(rng), size(rng), size(rng));
    boxes.push_back(box_of(c - h, c + h));
    if (boxes.size() % 997 == 0) {
      // Rods crossing at c, and the same box twice.
      boxes.push_back(box_of(c - Vec3(0.05, 0.001, 0.001), c + Vec3(0.05, 0.001, 0.001)));
      boxes.push_back(box_of(c - Vec3(0.001, 0.05, 0.001), c + Vec3(0.001, 0.05, 0.001)));
      boxes.push_back(boxes.back());
    }
  }
  const Bvh one = build_bvh(boxes, 1);
  for (const int threads : {2, 3, 8}) {
    const Bvh many = build_bvh(boxes, threads);
    ASSERT_EQ(one.order, many.order) << threads << " threads";
    ASSERT_EQ(one.nodes.size(), many.nodes.size()) << threads << " threads";
    for (size_t i = 0; i < one.nodes.size(); ++i) {
      const BvhNode &a = one.nodes[i], &b = many.nodes[i];
      ASSERT_EQ(a.first, b.first) << "node " << i << ", " << threads << " threads";
      ASSERT_EQ(a.count, b.count) << "node " << i << ", " << threads << " threads";
      ASSERT_TRUE(a.box.lo == b.box.lo && a.box.hi == b.box.hi)
          << "node " << i << ", " << threads << " threads";
    }
    expect_same_wide(one.wide, many.wide, threads);
    expect_same_wide(one.wide8, many.wide8, threads);
  }
  // The tree is a real one: every primitive in one leaf, reached from the
  // root.
  std::vector<int> seen(boxes.size(), 0);
  std::vector<int> stack = {0};
  while (!stack.empty()) {
    const BvhNode& n = one.nodes[stack.back()];
    const int id = stack.back();
    stack.pop_back();
    if (n.count > 0) {
      for (int i = n.first; i < n.first + n.count; ++i) ++seen[one.order[i]];
    } else {
      stack.push_back(id + 1);
      stack.push_back(n.first);
    }
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(boxes.size()));
}

}  // namespace
}  // namespace locus
