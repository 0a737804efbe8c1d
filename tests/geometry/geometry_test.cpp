// Seeded property tests of every primitive's intersection: random rays are
// intersected, hit points must lie on the surface, normals be unit length
// and outward, and re-intersecting from just before a hit must find it again.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "common/geometry/bvh.h"
#include "common/geometry/geometry.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene.h"
#include "tests/random_unit.h"

namespace locus {
namespace {

constexpr int kRays = 4000;

// A ray from a random point on a sphere of radius 4 around the origin,
// aimed at a random point inside the unit ball.
Ray random_ray(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const Vec3 o = 4.0 * random_unit(rng);
  const Vec3 target(u(rng), u(rng), u(rng));
  return Ray{o, glm::normalize(target - o)};
}

Scene scene_with(Shape shape, const Mat4& xf = Mat4(1.0)) {
  Scene s;
  s.materials.push_back(Material{});
  Object o;
  o.shape = std::move(shape);
  o.world_from_object = xf;
  s.objects.push_back(std::move(o));
  return s;
}

// Checks each hit with `on_surface(p, n)` which returns the signed distance
// of p to the surface and the expected outward normal.
template <typename Surface>
void check_shape(const Scene& scene, uint64_t seed, Surface on_surface, int min_hits) {
  std::mt19937_64 rng(seed);
  const PrimitiveSet set = build_primitives(scene);
  ASSERT_FALSE(set.prims.empty());
  int hits = 0;
  for (int i = 0; i < kRays; ++i) {
    const Ray ray = random_ray(rng);
    std::vector<Crossing> all;
    for (int p = 0; p < static_cast<int>(set.prims.size()); ++p) {
      intersect_all(set, p, ray, 0.0, 1e9, all);
    }
    for (const Crossing& c : all) {
      ++hits;
      const Vec3 x = ray.origin + c.t * ray.dir;
      Vec3 expected_n;
      const double dist = on_surface(x, &expected_n);
      ASSERT_NEAR(dist, 0.0, 1e-9) << "seed " << seed << " ray " << i << " t " << c.t;
      ASSERT_NEAR(glm::length(c.normal), 1.0, 1e-12) << "seed " << seed << " ray " << i;
      ASSERT_GT(glm::dot(c.normal, expected_n), 1.0 - 1e-9)
          << "seed " << seed << " ray " << i << " normal not outward";
    }
    // Consistency: the nearest crossing is the smallest of all crossings.
    for (int p = 0; p < static_cast<int>(set.prims.size()); ++p) {
      std::vector<Crossing> one;
      intersect_all(set, p, ray, 0.0, 1e9, one);
      const auto n = intersect_nearest(set, p, ray, 0.0, 1e9);
      ASSERT_EQ(n.has_value(), !one.empty()) << "seed " << seed << " ray " << i;
      // intersect_any (opaque shadow tests) agrees with intersect_all on
      // segments that start and end anywhere: before, inside or beyond the
      // body.
      for (const double t0 : {0.0, 3.0, 4.0}) {
        for (const double t1 : {2.5, 3.5, 4.0, 4.5, 6.0, 1e9}) {
          if (!(t1 > t0)) continue;
          std::vector<Crossing> cut;
          intersect_all(set, p, ray, t0, t1, cut);
          ASSERT_EQ(intersect_any(set, p, ray, t0, t1), !cut.empty())
              << "seed " << seed << " ray " << i << " t in (" << t0 << ", " << t1 << ")";
        }
      }
      if (n) {
        ASSERT_EQ(n->t, one.front().t);
        // Starting just before the hit finds the same point again.
        const Ray again{ray.origin + (n->t - 1e-3) * ray.dir, ray.dir};
        const auto m = intersect_nearest(set, p, again, 0.0, 1e9);
        ASSERT_TRUE(m.has_value()) << "seed " << seed << " ray " << i;
        ASSERT_NEAR(m->t, 1e-3, 1e-9);
      }
    }
  }
  EXPECT_GE(hits, min_hits) << "too few rays hit; the test would prove little";
}

TEST(Geometry, SphereProperty) {
  const Sphere s{Vec3(0.1, -0.2, 0.3), 0.7};
  check_shape(scene_with(s), 1, [&](const Vec3& p, Vec3* n) {
    *n = glm::normalize(p - s.center);
    return glm::length(p - s.center) - s.radius;
  }, kRays / 2);
}

TEST(Geometry, TransformedSphereIsEllipsoid) {
  // Non-uniform scale: an ellipsoid with semi-axes 0.9, 0.4, 0.6.
  const Mat4 xf = glm::scale(Mat4(1.0), Vec3(0.9, 0.4, 0.6));
  check_shape(scene_with(Sphere{Vec3(0), 1.0}, xf), 2, [](const Vec3& p, Vec3* n) {
    const Vec3 q = p / Vec3(0.9, 0.4, 0.6);
    *n = glm::normalize(p / (Vec3(0.81, 0.16, 0.36)));
    // Distance-like residual, scaled to be ~ distance near the surface.
    return (glm::length(q) - 1.0) * 0.4;
  }, kRays / 2);
}

// Distance from p to a cone/frustum surface with the given axis and radii
// (side only), and the outward normal there.
double cone_residual(const Cone& c, const Vec3& p, Vec3* n) {
  const Vec3 axis = c.apex - c.base;
  const double h = glm::length(axis);
  const Vec3 a = axis / h;
  const double s = glm::dot(p - c.base, a);
  const Vec3 q = (p - c.base) - s * a;
  const double r = glm::length(q);
  const double k = (c.apex_radius - c.base_radius) / h;
  const double expected_r = c.base_radius + k * s;
  if (c.capped && (std::fabs(s) < 1e-9 || std::fabs(s - h) < 1e-9)) {
    *n = std::fabs(s) < 1e-9 ? -a : a;
    const double cap_r = std::fabs(s) < 1e-9 ? c.base_radius : c.apex_radius;
    return r <= cap_r + 1e-9 ? 0.0 : r - cap_r;
  }
  *n = glm::normalize(q / r - k * a);
  EXPECT_GE(s, -1e-9);
  EXPECT_LE(s, h + 1e-9);
  return (r - expected_r) / std::sqrt(1 + k * k);
}

TEST(Geometry, OpenCylinderProperty) {
  const Cone c{Vec3(-0.3, -0.5, 0.1), 0.4, Vec3(0.4, 0.6, -0.2), 0.4, false};
  check_shape(scene_with(c), 3, [&](const Vec3& p, Vec3* n) { return cone_residual(c, p, n); },
              kRays / 3);
}

TEST(Geometry, CappedFrustumProperty) {
  const Cone c{Vec3(0.2, -0.6, 0.0), 0.6, Vec3(-0.1, 0.7, 0.3), 0.2, true};
  check_shape(scene_with(c), 4, [&](const Vec3& p, Vec3* n) { return cone_residual(c, p, n); },
              kRays / 2);
}

TEST(Geometry, ConeProperty) {
  const Cone c{Vec3(0, 0, -0.7), 0.8, Vec3(0, 0.2, 0.8), 0.0, true};
  check_shape(scene_with(c), 5, [&](const Vec3& p, Vec3* n) { return cone_residual(c, p, n); },
              kRays / 2);
}

// Distance to the boundary of a convex polyhedron given as planes, and the
// normal of the face the point lies on.
double box_residual(const Vec3& lo, const Vec3& hi, const Vec3& p, Vec3* n) {
  double best = 1e9;
  for (int a = 0; a < 3; ++a) {
    for (int side = 0; side < 2; ++side) {
      const double d = std::fabs(p[a] - (side ? hi[a] : lo[a]));
      if (d < best) {
        best = d;
        *n = Vec3(0.0);
        (*n)[a] = side ? 1.0 : -1.0;
      }
    }
  }
  return best;
}

TEST(Geometry, BoxProperty) {
  const Vec3 lo(-0.5, -0.3, -0.8), hi(0.6, 0.4, 0.2);
  check_shape(scene_with(make_box(lo, hi)), 6,
              [&](const Vec3& p, Vec3* n) { return box_residual(lo, hi, p, n); }, kRays / 2);
}

TEST(Geometry, RotatedBoxProperty) {
  const Mat4 xf = glm::rotate(Mat4(1.0), 0.7, glm::normalize(Vec3(1, 2, 3)));
  const Mat4 inv = glm::inverse(xf);
  const Vec3 lo(-0.5, -0.3, -0.8), hi(0.6, 0.4, 0.2);
  check_shape(scene_with(make_box(lo, hi), xf), 7, [&](const Vec3& p, Vec3* n) {
    Vec3 local_n;
    const double d = box_residual(lo, hi, transform_point(inv, p), &local_n);
    *n = glm::normalize(transform_vector(xf, local_n));
    return d;
  }, kRays / 2);
}

TEST(Geometry, ConcavePolygon) {
  // An L shape in the z = 0.1 plane, CCW seen from +z.
  Polygon poly{{Vec3(-1, -1, 0.1), Vec3(1, -1, 0.1), Vec3(1, 0, 0.1), Vec3(0, 0, 0.1),
                Vec3(0, 1, 0.1), Vec3(-1, 1, 0.1)}};
  const PrimitiveSet set = build_primitives(scene_with(poly));
  auto hit_at = [&](double x, double y) {
    return intersect_nearest(set, 0, Ray{Vec3(x, y, 5), Vec3(0, 0, -1)}, 0, 1e9);
  };
  EXPECT_TRUE(hit_at(-0.5, -0.5).has_value());
  EXPECT_TRUE(hit_at(0.5, -0.5).has_value());
  EXPECT_TRUE(hit_at(-0.5, 0.5).has_value());
  EXPECT_FALSE(hit_at(0.5, 0.5).has_value());  // the notch
  EXPECT_FALSE(hit_at(1.5, 0.0).has_value());
  const auto h = hit_at(-0.5, -0.5);
  EXPECT_NEAR(h->t, 4.9, 1e-12);
  EXPECT_NEAR(h->normal.z, 1.0, 1e-12);  // CCW seen from +z: front is +z
}

TEST(Geometry, TriangleMeshWithNormals) {
  Mesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.normals = {Vec3(0, 0, 1), glm::normalize(Vec3(1, 0, 1)), glm::normalize(Vec3(0, 1, 1))};
  m.triangles = {{0, 1, 2}};
  const PrimitiveSet set = build_primitives(scene_with(m));
  const auto h = intersect_nearest(set, 0, Ray{Vec3(0.25, 0.25, 1), Vec3(0, 0, -1)}, 0, 1e9);
  ASSERT_TRUE(h.has_value());
  EXPECT_NEAR(h->t, 1.0, 1e-12);
  EXPECT_NEAR(h->normal.z, 1.0, 1e-12);
  const Vec3 ns = shading_normal(set, set.prims[0], *h);
  EXPECT_NEAR(glm::length(ns), 1.0, 1e-12);
  const Vec3 expect = glm::normalize(0.5 * m.normals[0] + 0.25 * m.normals[1] + 0.25 * m.normals[2]);
  EXPECT_NEAR(glm::dot(ns, expect), 1.0, 1e-12);
}

// CSG: compare against point-membership classification along random rays.
TEST(Geometry, CsgMatchesPointMembership) {
  for (CsgOp op : {CsgOp::kUnion, CsgOp::kIntersection, CsgOp::kDifference}) {
    Scene s;
    s.materials.push_back(Material{});
    Object a, b, c;
    a.shape = Sphere{Vec3(-0.25, 0, 0), 0.6};
    b.shape = make_box(Vec3(-0.2, -0.4, -0.4), Vec3(0.7, 0.4, 0.4));
    c.shape = Csg{op, 0, 1};
    s.objects = {a, b, c};
    const PrimitiveSet set = build_primitives(s);
    ASSERT_EQ(set.prims.size(), 1u) << "operands must not render on their own";
    auto in_a = [](const Vec3& p) { return glm::length(p - Vec3(-0.25, 0, 0)) < 0.6; };
    auto in_b = [](const Vec3& p) {
      return p.x > -0.2 && p.x < 0.7 && std::fabs(p.y) < 0.4 && std::fabs(p.z) < 0.4;
    };
    auto inside = [&](const Vec3& p) {
      switch (op) {
        case CsgOp::kUnion: return in_a(p) || in_b(p);
        case CsgOp::kIntersection: return in_a(p) && in_b(p);
        case CsgOp::kDifference: return in_a(p) && !in_b(p);
      }
      return false;
    };
    std::mt19937_64 rng(100 + static_cast<int>(op));
    int crossings = 0;
    for (int i = 0; i < kRays; ++i) {
      const Ray ray = random_ray(rng);
      std::vector<Crossing> all;
      intersect_all(set, 0, ray, 0.0, 1e9, all);
      // March along the ray: membership must flip exactly at the crossings.
      for (size_t k = 0; k < all.size(); ++k) {
        ++crossings;
        const Vec3 p = ray.origin + all[k].t * ray.dir;
        const bool before = inside(p - 1e-6 * ray.dir), after = inside(p + 1e-6 * ray.dir);
        ASSERT_NE(before, after) << "op " << static_cast<int>(op) << " ray " << i;
        // Outward normal: entering iff the ray goes against it.
        ASSERT_EQ(after, glm::dot(all[k].normal, ray.dir) < 0) << "op " << static_cast<int>(op);
        if (k > 0) {
          ASSERT_GT(all[k].t, all[k - 1].t);
        }
      }
      const bool start_in = inside(ray.origin), end_in = inside(ray.origin + 10.0 * ray.dir);
      ASSERT_FALSE(start_in);
      ASSERT_FALSE(end_in);
      ASSERT_EQ(all.size() % 2, 0u);
    }
    EXPECT_GT(crossings, kRays / 4);
  }
}

// A bent polygon (a corner off the plane of the others) is hit on its
// best-fit plane, inside its outline dropped on two axes. Those hits can lie
// outside the box of its vertices, so its box must hold the outline that is
// hit (else the hierarchy misses them), and polygon_outline() must be that
// outline: on the plane, with the same 2D outline.
TEST(Geometry, BentPolygonBoxHoldsItsHits) {
  const Scene scene =
      scene_with(Polygon{{Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0.8)}});
  const PrimitiveSet set = build_primitives(scene);
  const PolygonPrim& p = set.polygons[0];
  const Aabb& box = set.bounds[0];
  for (const Vec3& v : polygon_outline(p)) {
    EXPECT_NEAR(glm::dot(p.normal, v), p.offset, 1e-12);
  }
  std::mt19937_64 rng(5);
  int hits = 0;
  for (int i = 0; i < kRays; ++i) {
    const Ray ray = random_ray(rng);
    std::vector<Crossing> c;
    if (!intersect_all(set, 0, ray, 0.0, 1e9, c)) continue;
    ++hits;
    const Vec3 x = ray.origin + c[0].t * ray.dir;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(x[a], box.lo[a] - 1e-12);
      EXPECT_LE(x[a], box.hi[a] + 1e-12);
    }
  }
  EXPECT_GT(hits, 100);
  EXPECT_LT(box.lo.z, 0.0) << "the plane dips below the vertices' box";
}

// A polygon of many vertices is tested through its edge buckets
// (PolygonPrim::bucket_first): the same crossings, bit for bit, as the test
// over every edge, on a concave gear-like outline (teeth, and vertices on
// the bucket boundaries' lines) with rays through its plane everywhere.
TEST(Geometry, PolygonEdgeBucketsGiveTheSameCrossings) {
  std::vector<Vec3> outline;
  constexpr int kTeeth = 24;
  for (int i = 0; i < 4 * kTeeth; ++i) {
    const double a = 2.0 * M_PI * i / (4 * kTeeth);
    const double r = (i % 4 < 2) ? 1.0 : 0.7;
    outline.emplace_back(r * std::cos(a), r * std::sin(a), 0.0);
  }
  const Scene scene = scene_with(Polygon{outline});
  const PrimitiveSet set = build_primitives(scene);
  ASSERT_FALSE(set.polygons[0].bucket_first.empty()) << "more than kPolygonBucketAbove vertices";
  PrimitiveSet plain = set;
  plain.polygons[0].bucket_first.clear();
  std::mt19937_64 rng(27);
  int hits = 0;
  for (int i = 0; i < 4 * kRays; ++i) {
    Ray ray = random_ray(rng);
    if (i % 4 == 0) {
      // Through a vertex's v coordinate exactly: an edge's end on the line.
      const PolygonPrim& p = set.polygons[0];
      const Vec3 v = p.verts[i % p.verts.size()];
      Vec3 target = ray.origin + ray.dir;
      target[p.axis_v] = v[p.axis_v];
      ray.origin[p.axis_v] = v[p.axis_v];
      ray.dir = glm::normalize(target - ray.origin);
    }
    std::vector<Crossing> a, b;
    intersect_all(set, 0, ray, 0.0, 1e9, a);
    intersect_all(plain, 0, ray, 0.0, 1e9, b);
    ASSERT_EQ(a.size(), b.size()) << "ray " << i;
    for (size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a[k].t, b[k].t);
    hits += static_cast<int>(a.size());
  }
  EXPECT_GT(hits, kRays / 2);
}


// hit_box (SSE2 where built with it) against the scalar slab loop it
// replaced, comparison for comparison: random boxes and rays, and rays whose
// origin lies on a slab's plane with a direction component of +0 or -0
// (NaN slab distances), on a box's face or edge, and with tmax at the
// entry distance.
TEST(Geometry, SlabTestMatchesScalarLoop) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::uniform_int_distribution<int> pick(0, 5);
  const double grid[] = {-1.0, -0.5, 0.0, 0.5, 1.0};
  int hits = 0, misses = 0;
  for (int k = 0; k < 200000; ++k) {
    Aabb b;
    b.extend(Vec3(grid[pick(rng) % 5], grid[pick(rng) % 5], grid[pick(rng) % 5]));
    b.extend(Vec3(grid[pick(rng) % 5], grid[pick(rng) % 5], grid[pick(rng) % 5]));
    Vec3 o(u(rng), u(rng), u(rng)), d(u(rng), u(rng), u(rng));
    for (int a = 0; a < 3; ++a) {
      switch (pick(rng)) {
        case 0: d[a] = 0.0; break;
        case 1: d[a] = -0.0; break;
        case 2: o[a] = grid[pick(rng) % 5]; break;  // on a slab plane
        case 3: o[a] = grid[pick(rng) % 5]; d[a] = pick(rng) % 2 ? 0.0 : -0.0; break;
        default: break;
      }
    }
    const RayInv r(Ray{o, d});
    const double tmin = pick(rng) % 2 ? 0.0 : -1e300;
    const double tmax = pick(rng) % 3 == 0 ? std::abs(u(rng)) : 1e300;
    const bool want = hit_box_scalar(b, r, tmin, tmax);
    ASSERT_EQ(hit_box(b, r, tmin, tmax), want)
        << "box (" << b.lo.x << ", " << b.lo.y << ", " << b.lo.z << ")-(" << b.hi.x << ", "
        << b.hi.y << ", " << b.hi.z << ") origin (" << o.x << ", " << o.y << ", " << o.z
        << ") direction (" << d.x << ", " << d.y << ", " << d.z << ")";
    (want ? hits : misses)++;
  }
  // Both outcomes are well represented.
  EXPECT_GT(hits, 5000);
  EXPECT_GT(misses, 20000);
}

}  // namespace
}  // namespace locus
