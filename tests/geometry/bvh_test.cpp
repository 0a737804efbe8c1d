// The one hierarchy walk (walk_bvh, traverse_bvh): on seeded random boxes
// and rays it visits exactly the leaves a brute-force box test gives, and a
// hierarchy deeper than its stack trips the LOCUS_CHECK instead of writing
// past the array.
#include "common/geometry/bvh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
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

TEST(BvhWalk, TraversalVisitsExactlyTheLeavesTheRayMeets) {
  const uint64_t seed = 22;
  std::mt19937_64 rng(seed);
  const std::vector<Aabb> boxes = random_boxes(rng);
  const Bvh bvh = build_bvh(boxes);
  for (int k = 0; k < kRays; ++k) {
    const TestRay r = random_ray(rng);
    const RayInv ri(r.ray);
    std::vector<int> visited;
    traverse_bvh(bvh, r.ray, 0.0, r.tmax, [&](int prim) {
      visited.push_back(prim);
      return r.tmax;
    });
    std::sort(visited.begin(), visited.end());
    const std::vector<int> expected =
        brute_force_leaves(bvh, [&](const Aabb& b) { return hit_box(b, ri, 0.0, r.tmax); });
    ASSERT_EQ(visited, expected) << "seed " << seed << ", ray " << k;
    // Conservative: every primitive whose own box the ray meets is visited.
    for (int p = 0; p < kBoxes; ++p) {
      if (hit_box_scalar(boxes[p], ri, 0.0, r.tmax)) {
        ASSERT_TRUE(std::binary_search(visited.begin(), visited.end(), p))
            << "seed " << seed << ", ray " << k << ", box " << p;
      }
    }
  }
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
  return bvh;
}

TEST(BvhWalkDeathTest, DeeperThanTheStackTripsTheCheck) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const Bvh bvh = degenerate_chain(kBvhWalkStack);
  EXPECT_DEATH(walk_bvh(
                   bvh, [](int) { return true; }, [](int) { return true; }),
               "CHECK failed: sp \\+ 2 <= kBvhWalkStack");
  // traverse_bvh walks it left first too (the children's centres coincide
  // and the ray points along +z).
  EXPECT_DEATH(traverse_bvh(bvh, Ray{Vec3(0.1, 0.2, -5), Vec3(0, 0, 1)}, 0.0, 10.0,
                            [](int) { return 10.0; }),
               "CHECK failed: sp \\+ 2 <= kBvhWalkStack");
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

}  // namespace
}  // namespace locus
