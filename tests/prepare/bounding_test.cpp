// Bounding polyhedra of curved bodies (common/prepare/bounding.cpp; paper §3.1,
// Fig. 3). Seeded property tests: random spheres, ellipsoids, cylinders,
// frusta and cones under random affine maps; thousands of points on each
// body's surface must satisfy every face's half-space, every face must be
// planar, outward and touch the body. BoundingTightness.Table prints the
// figures of docs/bounding.md.
#include "common/prepare/bounding.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <utility>

#include "common/geometry/geometry.h"
#include "common/scene/polyhedron.h"
#include "tests/random_unit.h"

namespace locus {
namespace {

constexpr int kBodies = 300;          // random bodies per kind
constexpr int kPointsPerBody = 2000;  // surface points per body
constexpr double kPi = std::numbers::pi;

// ---- Geometry of polyhedra, computed here independently of bounding.cpp ----

struct Plane {
  Vec3 n;    // outward, unit
  double d;  // n . x <= d inside
};

// Newell's vector: twice the face's area times its unit normal.
Vec3 area_vector(const Polyhedron& p, const std::vector<int>& face) {
  Vec3 n(0.0);
  for (size_t i = 0; i < face.size(); ++i) {
    n += glm::cross(p.vertices[face[i]], p.vertices[face[(i + 1) % face.size()]]);
  }
  return n;
}

Plane face_plane(const Polyhedron& p, const std::vector<int>& face) {
  const Vec3 n = glm::normalize(area_vector(p, face));
  double d = 0.0;
  for (int v : face) d += glm::dot(n, p.vertices[v]);
  return Plane{n, d / static_cast<double>(face.size())};
}

double size_of(const Polyhedron& p) {
  Aabb b;
  for (const Vec3& v : p.vertices) b.extend(v);
  return glm::length(b.hi - b.lo);
}

double volume(const Polyhedron& p) {
  double v = 0.0;  // divergence theorem over fan triangles
  for (const auto& f : p.faces) {
    for (size_t i = 1; i + 1 < f.size(); ++i) {
      v += glm::dot(p.vertices[f[0]], glm::cross(p.vertices[f[i]], p.vertices[f[i + 1]]));
    }
  }
  return v / 6.0;
}

// Orthographic projected area along unit d: front and back faces each cover
// the convex shadow once.
double projected_area(const Polyhedron& p, const Vec3& d) {
  double a = 0.0;
  for (const auto& f : p.faces) a += std::abs(glm::dot(area_vector(p, f), d));
  return a / 4.0;  // area vectors are twice the area; two layers
}

// Convex, closed, consistently wound outward: each face planar with every
// vertex of the polyhedron behind it and the centroid strictly behind it;
// each edge used once in each direction; V - E + F = 2.
void expect_valid_polyhedron(const Polyhedron& p) {
  const double tol = 1e-9 * size_of(p);
  ASSERT_GE(p.faces.size(), 4u);
  Vec3 centroid(0.0);
  for (const Vec3& v : p.vertices) centroid += v;
  centroid /= static_cast<double>(p.vertices.size());
  std::map<std::pair<int, int>, int> edges;
  for (size_t f = 0; f < p.faces.size(); ++f) {
    const auto& face = p.faces[f];
    ASSERT_GE(face.size(), 3u) << "face " << f;
    const Plane pl = face_plane(p, face);
    for (int v : face)
      EXPECT_NEAR(glm::dot(pl.n, p.vertices[v]), pl.d, tol) << "face " << f << " not planar";
    for (const Vec3& v : p.vertices)
      EXPECT_LE(glm::dot(pl.n, v) - pl.d, tol) << "face " << f << " not convex";
    EXPECT_GT(pl.d - glm::dot(pl.n, centroid), 1e-6 * size_of(p))
        << "face " << f << " points inward";
    for (size_t i = 0; i < face.size(); ++i) ++edges[{face[i], face[(i + 1) % face.size()]}];
  }
  for (const auto& [e, count] : edges) {
    EXPECT_EQ(count, 1) << "edge " << e.first << "-" << e.second;
    EXPECT_EQ(edges.count({e.second, e.first}), 1u)
        << "edge " << e.first << "-" << e.second << " unpaired";
  }
  EXPECT_EQ(static_cast<long>(p.vertices.size()) - static_cast<long>(edges.size() / 2) +
                static_cast<long>(p.faces.size()),
            2);
}

// ---- Bodies: support functions and surface samples ----

// Support function h(n) = max over the body of n . x, exact. For x = M p the
// object-space direction is L^T n (L the linear part of M). A sphere's is
// c + r |m|; a solid frustum is the hull of its end disks, and a disk's is
// c + r |m minus its axial part|.
double support(const Sphere& s, const Mat4& m, const Vec3& n) {
  const Vec3 mo = glm::transpose(glm::dmat3(m)) * n;
  return glm::dot(n, transform_point(m, s.center)) + s.radius * glm::length(mo);
}

double support(const Cone& c, const Mat4& m, const Vec3& n) {
  const Vec3 mo = glm::transpose(glm::dmat3(m)) * n;
  const Vec3 a = glm::normalize(c.apex - c.base);
  const double radial = glm::length(mo - glm::dot(mo, a) * a);
  return std::max(glm::dot(n, transform_point(m, c.base)) + c.base_radius * radial,
                  glm::dot(n, transform_point(m, c.apex)) + c.apex_radius * radial);
}

// A point on the body's surface, in world space. For a cone: the side, or
// a cap disk (the polyhedron is the same for open and capped bodies). The
// radial frame is drawn at random, unrelated to the polyhedron's squares.
Vec3 surface_point(const Sphere& s, const Mat4& m, std::mt19937_64& rng) {
  return transform_point(m, s.center + s.radius * random_unit(rng));
}

Vec3 surface_point(const Cone& c, const Mat4& m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const Vec3 a = glm::normalize(c.apex - c.base);
  Vec3 e1 = random_unit(rng);
  e1 = e1 - glm::dot(e1, a) * a;
  if (glm::length(e1) < 1e-3) e1 = any_perpendicular(a);
  e1 = glm::normalize(e1);
  const Vec3 e2 = glm::cross(a, e1);
  const double phi = 2.0 * kPi * u01(rng);
  const Vec3 radial = std::cos(phi) * e1 + std::sin(phi) * e2;
  const double pick = u01(rng);
  Vec3 p;
  if (pick < 0.7) {  // side
    const double s = u01(rng);
    p = c.base + s * (c.apex - c.base) + ((1 - s) * c.base_radius + s * c.apex_radius) * radial;
  } else if (pick < 0.85) {  // base cap
    p = c.base + c.base_radius * std::sqrt(u01(rng)) * radial;
  } else {  // apex cap
    p = c.apex + c.apex_radius * std::sqrt(u01(rng)) * radial;
  }
  return transform_point(m, p);
}

// A random affine map: rotation, optional non-uniform scale (ellipsoids,
// elliptic cylinders), optional shear and mirror, translation.
Mat4 random_transform(std::mt19937_64& rng, bool non_uniform) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), angle(0.0, 2.0 * kPi);
  std::uniform_real_distribution<double> log_scale(std::log(0.2), std::log(5.0));
  Mat4 m = glm::translate(Mat4(1.0), 10.0 * Vec3(u(rng), u(rng), u(rng)));
  m = glm::rotate(m, angle(rng), random_unit(rng));
  if (non_uniform) {
    m = glm::scale(
        m, Vec3(std::exp(log_scale(rng)), std::exp(log_scale(rng)), std::exp(log_scale(rng))));
    Mat4 shear(1.0);
    shear[1][0] = 0.5 * u(rng);  // x += k y
    shear[2][1] = 0.5 * u(rng);  // y += k z
    m = m * shear;
    if (u(rng) < -0.5) m = glm::scale(m, Vec3(-1.0, 1.0, 1.0));
    m = glm::rotate(m, angle(rng), random_unit(rng));
  } else {
    m = glm::scale(m, Vec3(std::exp(log_scale(rng))));
  }
  return m;
}

enum class ConeKind { kCylinder, kFrustum, kCone, kInvertedCone };

Cone random_cone(std::mt19937_64& rng, ConeKind kind) {
  std::uniform_real_distribution<double> u(-2.0, 2.0), r(0.05, 2.0);
  Cone c;
  c.base = Vec3(u(rng), u(rng), u(rng));
  c.apex = c.base + r(rng) * 2.0 * random_unit(rng);
  c.base_radius = r(rng);
  c.apex_radius = r(rng);
  if (kind == ConeKind::kCylinder) c.apex_radius = c.base_radius;
  if (kind == ConeKind::kCone) c.apex_radius = 0.0;
  if (kind == ConeKind::kInvertedCone) c.base_radius = 0.0;
  c.capped = u(rng) > 0.0;
  return c;
}

// Every surface point satisfies every face's half-space; every face is
// tangent to the body (its support equals the face offset: the polyhedron
// cannot be shrunk by moving any face in); the polyhedron is well formed.
template <typename Body>
void check_bounds(const Body& body, const Mat4& m, std::mt19937_64& rng) {
  const Polyhedron p = bounding_polyhedron(body, m);
  expect_valid_polyhedron(p);
  const double tol = 1e-9 * size_of(p);
  std::vector<Plane> planes;
  for (const auto& f : p.faces) planes.push_back(face_plane(p, f));
  for (size_t f = 0; f < planes.size(); ++f) {
    EXPECT_NEAR(support(body, m, planes[f].n), planes[f].d, tol)
        << "face " << f << " does not touch";
  }
  int outside = 0;
  double worst = 0.0;
  for (int i = 0; i < kPointsPerBody; ++i) {
    const Vec3 x = surface_point(body, m, rng);
    for (const Plane& pl : planes) {
      const double excess = glm::dot(pl.n, x) - pl.d;
      if (excess > tol) ++outside, worst = std::max(worst, excess);
    }
  }
  EXPECT_EQ(outside, 0) << "worst excess " << worst << " (tolerance " << tol << ")";
}

// ---- Property tests ----

TEST(Bounding, SpheresAndEllipsoidsInsideTheirPolyhedra) {
  for (bool non_uniform : {false, true}) {
    for (int i = 0; i < kBodies; ++i) {
      const uint64_t seed = 1000 + i + (non_uniform ? 100000 : 0);
      SCOPED_TRACE("seed " + std::to_string(seed));
      std::mt19937_64 rng(seed);
      std::uniform_real_distribution<double> u(-3.0, 3.0), r(0.01, 4.0);
      const Sphere s{Vec3(u(rng), u(rng), u(rng)), r(rng)};
      const Mat4 m = i == 0 ? Mat4(1.0) : random_transform(rng, non_uniform);
      check_bounds(s, m, rng);
      if (HasFailure()) return;
    }
  }
}

TEST(Bounding, CylindersFrustaAndConesInsideTheirPolyhedra) {
  for (ConeKind kind :
       {ConeKind::kCylinder, ConeKind::kFrustum, ConeKind::kCone, ConeKind::kInvertedCone}) {
    for (bool non_uniform : {false, true}) {
      for (int i = 0; i < kBodies; ++i) {
        const uint64_t seed =
            2000 + i + (non_uniform ? 100000 : 0) + 1000000 * static_cast<uint64_t>(kind);
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937_64 rng(seed);
        const Cone c = random_cone(rng, kind);
        const Mat4 m = i == 0 ? Mat4(1.0) : random_transform(rng, non_uniform);
        check_bounds(c, m, rng);
        if (HasFailure()) return;
      }
    }
  }
}

// Paper Fig. 3: the end squares circumscribe the end circles and are
// aligned with the axis; the sides touch the cylinder along four generators.
TEST(Bounding, CylinderHexahedronIsFig3) {
  const Cone c{Vec3(1, 2, 3), 0.5, Vec3(1, 2, 7), 0.5, true};
  const Polyhedron p = bounding_polyhedron(c, Mat4(1.0));
  ASSERT_EQ(p.vertices.size(), 8u);
  ASSERT_EQ(p.faces.size(), 6u);
  expect_valid_polyhedron(p);
  int at_base = 0, at_apex = 0;
  for (const Vec3& v : p.vertices) {
    // Corners of a square of half-side r lie r sqrt(2) from the axis.
    EXPECT_NEAR(glm::length(Vec2(v.x - 1, v.y - 2)), 0.5 * std::sqrt(2.0), 1e-12);
    at_base += std::abs(v.z - 3) < 1e-12;
    at_apex += std::abs(v.z - 7) < 1e-12;
  }
  EXPECT_EQ(at_base, 4);
  EXPECT_EQ(at_apex, 4);
  EXPECT_NEAR(volume(p), 4 * 0.25 * 4, 1e-12);  // (2r)^2 h
  // Each side face touches the side surface: its distance from the axis is r.
  for (const auto& f : p.faces) {
    const Plane pl = face_plane(p, f);
    if (std::abs(pl.n.z) > 0.5) continue;  // an end face
    EXPECT_NEAR(pl.d - glm::dot(pl.n, Vec3(1, 2, 0)), 0.5, 1e-12);
  }
}

TEST(Bounding, ConesArePyramidsAtEitherEnd) {
  for (bool pointed_apex : {true, false}) {
    SCOPED_TRACE(pointed_apex ? "apex radius 0" : "base radius 0");
    Cone c{Vec3(0, 0, 0), 1.0, Vec3(0, 3, 0), 1.0, false};
    (pointed_apex ? c.apex_radius : c.base_radius) = 0.0;
    const Polyhedron p = bounding_polyhedron(c, Mat4(1.0));
    EXPECT_EQ(p.vertices.size(), 5u);
    ASSERT_EQ(p.faces.size(), 5u);
    expect_valid_polyhedron(p);
    EXPECT_NEAR(volume(p), 4.0 * 3.0 / 3.0, 1e-12);  // square pyramid: (2r)^2 h / 3
    const Vec3 point = pointed_apex ? c.apex : c.base;
    EXPECT_EQ(std::count(p.vertices.begin(), p.vertices.end(), point), 1);
  }
}

TEST(Bounding, SphereIsCircumscribedIcosahedron) {
  const Sphere s{Vec3(1, -2, 0.5), 2.0};
  const Polyhedron p = bounding_polyhedron(s, Mat4(1.0));
  EXPECT_EQ(p.vertices.size(), 12u);
  EXPECT_EQ(p.faces.size(), 20u);
  expect_valid_polyhedron(p);
  for (const auto& f : p.faces) {
    EXPECT_EQ(f.size(), 3u);
    const Plane pl = face_plane(p, f);
    EXPECT_NEAR(pl.d - glm::dot(pl.n, s.center), s.radius, 1e-12);
  }
  // Regular icosahedron of inradius r: edge a = 2 sqrt(3) r / phi^2, volume
  // 5 (3 + sqrt 5) a^3 / 12, 1.2066 times the ball's.
  const double a = 2.0 * std::sqrt(3.0) * s.radius / (std::numbers::phi * std::numbers::phi);
  EXPECT_NEAR(volume(p), 5.0 * (3.0 + std::sqrt(5.0)) * a * a * a / 12.0, 1e-9);
}

TEST(Bounding, MirroringTransformKeepsFacesOutward) {
  const Mat4 mirror = glm::scale(Mat4(1.0), Vec3(-1.0, 2.0, 1.0));
  expect_valid_polyhedron(bounding_polyhedron(Sphere{}, mirror));
  expect_valid_polyhedron(bounding_polyhedron(Cone{}, mirror));
  expect_valid_polyhedron(transform_polyhedron(make_box(Vec3(0.0), Vec3(1.0)), mirror));
}

TEST(Bounding, CircumscribedPolyhedronNeedsNormalsAllAround) {
  // All normals in one hemisphere: the planes leave the volume open.
  EXPECT_FALSE(
      circumscribed_polyhedron({Vec3(0, 0, 1), glm::normalize(Vec3(1, 0, 1)),
                                glm::normalize(Vec3(0, 1, 1)), glm::normalize(Vec3(-1, -1, 1))}));
  const auto cube = circumscribed_polyhedron({Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0),
                                              Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)});
  ASSERT_TRUE(cube);
  EXPECT_EQ(cube->faces.size(), 6u);
  EXPECT_NEAR(volume(*cube), 8.0, 1e-12);
}

// The scene-level call: object transforms applied, CSG transforms composed
// down the tree. Every point where a ray crosses the CSG surface, as the
// renderer's own intersection finds it (common/geometry/intersect.cpp), lies in one of the
// leaves' polyhedra.
TEST(Bounding, SceneObjectsAndCsgLeaves) {
  Scene scene;
  scene.materials.push_back(Material{});
  auto add = [&](Shape shape, const Mat4& xf) {
    scene.objects.push_back(Object{std::move(shape), 0, xf, "", ""});
    return static_cast<int>(scene.objects.size()) - 1;
  };
  const Mat4 tilt = glm::rotate(Mat4(1.0), 0.7, glm::normalize(Vec3(1, 1, 0)));
  const Mat4 squash = glm::scale(Mat4(1.0), Vec3(1.0, 0.5, 2.0));
  const Mat4 shift = glm::translate(Mat4(1.0), Vec3(0.3, -0.2, 0.1));
  const int sphere = add(Sphere{Vec3(0.0), 1.0}, squash);
  const int cone = add(Cone{Vec3(0, 0, -1), 0.6, Vec3(0, 0, 1.5), 0.6, true}, tilt);
  const int box = add(make_box(Vec3(-0.5), Vec3(0.5)), shift);
  const int inner = add(Csg{CsgOp::kUnion, sphere, cone}, shift);
  const int root = add(Csg{CsgOp::kDifference, inner, box}, tilt * squash);
  const int polygon = add(Polygon{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}}, Mat4(1.0));
  const int mesh =
      add(Mesh{{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {}, {{0, 1, 2}}}, Mat4(1.0));

  EXPECT_EQ(bounding_polyhedra(scene, sphere).size(), 1u);
  EXPECT_EQ(bounding_polyhedra(scene, polygon).size(), 0u);
  EXPECT_EQ(bounding_polyhedra(scene, mesh).size(), 0u);
  const auto box_alone = bounding_polyhedra(scene, box);
  ASSERT_EQ(box_alone.size(), 1u);
  EXPECT_EQ(box_alone[0].vertices[0], transform_point(shift, Vec3(-0.5)));

  const std::vector<Polyhedron> leaves = bounding_polyhedra(scene, root);
  ASSERT_EQ(leaves.size(), 3u);
  const Mat4 inner_xf = tilt * squash * shift;
  const Polyhedron expect_sphere =
      bounding_polyhedron(std::get<Sphere>(scene.objects[sphere].shape), inner_xf * squash);
  const Polyhedron expect_cone =
      bounding_polyhedron(std::get<Cone>(scene.objects[cone].shape), inner_xf * tilt);
  for (size_t i = 0; i < expect_sphere.vertices.size(); ++i) {
    EXPECT_NEAR(glm::length(leaves[0].vertices[i] - expect_sphere.vertices[i]), 0.0, 1e-12);
  }
  for (size_t i = 0; i < expect_cone.vertices.size(); ++i) {
    EXPECT_NEAR(glm::length(leaves[1].vertices[i] - expect_cone.vertices[i]), 0.0, 1e-12);
  }
  for (const Polyhedron& p : leaves) expect_valid_polyhedron(p);

  // Cross-check against the renderer's CSG intersection.
  std::vector<std::vector<Plane>> planes(leaves.size());
  for (size_t l = 0; l < leaves.size(); ++l) {
    for (const auto& f : leaves[l].faces) planes[l].push_back(face_plane(leaves[l], f));
  }
  const PrimitiveSet set = build_primitives(scene);
  int csg_prim = -1;
  for (size_t i = 0; i < set.prims.size(); ++i) {
    if (set.prims[i].object == root) csg_prim = static_cast<int>(i);
  }
  ASSERT_GE(csg_prim, 0);
  std::mt19937_64 rng(77);
  int hits = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 o = 8.0 * random_unit(rng);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    const Ray ray{o, glm::normalize(Vec3(u(rng), u(rng), u(rng)) - o)};
    std::vector<Crossing> xs;
    intersect_all(set, csg_prim, ray, 0.0, 1e9, xs);
    for (const Crossing& x : xs) {
      ++hits;
      const Vec3 p = ray.origin + x.t * ray.dir;
      bool inside_some = false;
      for (const auto& pl : planes) {
        bool inside = true;
        for (const Plane& h : pl) inside = inside && glm::dot(h.n, p) - h.d <= 1e-9;
        inside_some = inside_some || inside;
      }
      EXPECT_TRUE(inside_some) << "CSG surface point outside every leaf polyhedron, ray " << i;
      if (HasFailure()) return;
    }
  }
  EXPECT_GT(hits, 1000);
}

// ---- Tightness against world-axis boxes (paper Fig. 3; docs/bounding.md) ----

// The tightest world-axis box of a body, from its support function.
template <typename Body>
Polyhedron world_box(const Body& body, const Mat4& m) {
  Vec3 lo, hi;
  for (int a = 0; a < 3; ++a) {
    Vec3 e(0.0);
    e[a] = 1.0;
    hi[a] = support(body, m, e);
    lo[a] = -support(body, m, -e);
  }
  return make_box(lo, hi);
}

// Orthographic projected area of the body along unit d: a linear map L
// carries area vectors by its cofactor det(L) L^-T, so the shadow of L K
// along d is |det(L) L^-1 d| times the shadow of K along that vector's
// direction.
double body_projected_area(const Sphere& s, const Mat4& m, const Vec3& d) {
  const glm::dmat3 l(m);
  return kPi * s.radius * s.radius * glm::length(glm::determinant(l) * (glm::inverse(l) * d));
}

double body_projected_area(const Cone& c, const Mat4& m, const Vec3& d) {  // cylinders only
  const glm::dmat3 l(m);
  const Vec3 w = glm::determinant(l) * (glm::inverse(l) * d);
  const Vec3 e = glm::normalize(w);
  const Vec3 a = c.apex - c.base;
  const double h = glm::length(a), cos_t = std::abs(glm::dot(e, a / h)), r = c.base_radius;
  return glm::length(w) *
         (kPi * r * r * cos_t + 2.0 * r * h * std::sqrt(std::max(0.0, 1.0 - cos_t * cos_t)));
}

double body_volume(const Sphere& s, const Mat4& m) {
  return 4.0 / 3.0 * kPi * std::pow(s.radius, 3) * std::abs(glm::determinant(glm::dmat3(m)));
}

double body_volume(const Cone& c, const Mat4& m) {  // cylinders only
  return kPi * c.base_radius * c.base_radius * glm::length(c.apex - c.base) *
         std::abs(glm::determinant(glm::dmat3(m)));
}

// Evenly spread view directions (a Fibonacci lattice on the sphere), for
// the mean shadow over all views.
std::vector<Vec3> view_directions(int n) {
  std::vector<Vec3> out;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z);
    out.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return out;
}

struct Tightness {
  double poly_volume, box_volume;  // over the body's volume
  double poly_front, box_front;    // shadow along z (the view), over the body's
  double poly_mean, box_mean;      // mean shadow over all views, over the body's
  double poly_worst;               // worst view, polyhedron over body
};

template <typename Body>
Tightness measure(const Body& body, const Mat4& m) {
  const Polyhedron p = bounding_polyhedron(body, m), b = world_box(body, m);
  Tightness t{};
  const double v = body_volume(body, m);
  t.poly_volume = volume(p) / v;
  t.box_volume = volume(b) / v;
  const Vec3 z(0, 0, 1);
  t.poly_front = projected_area(p, z) / body_projected_area(body, m, z);
  t.box_front = projected_area(b, z) / body_projected_area(body, m, z);
  const std::vector<Vec3> dirs = view_directions(4000);
  double pm = 0, bm = 0, body_m = 0;
  for (const Vec3& d : dirs) {
    const double ba = body_projected_area(body, m, d), pa = projected_area(p, d);
    pm += pa;
    bm += projected_area(b, d);
    body_m += ba;
    t.poly_worst = std::max(t.poly_worst, pa / ba);
  }
  t.poly_mean = pm / body_m;
  t.box_mean = bm / body_m;
  return t;
}

void print_row(const char* body, const std::string& tilt, const Tightness& t) {
  std::printf("| %s | %s | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f |\n", body,
              tilt.c_str(), t.poly_volume, t.box_volume, t.poly_volume / t.box_volume, t.poly_front,
              t.box_front, t.poly_front / t.box_front, t.poly_mean, t.box_mean);
}

// The table in docs/bounding.md. Bodies stand along the screen's vertical
// (y) and are tilted by theta about the view direction z, as in paper Fig. 3;
// "front" is the shadow seen along z, "mean" the mean over all views.
// Ratios are to the body's own volume or shadow: the shadow ratio is the
// number of pixels whose rays are traced per pixel the body covers.
TEST(BoundingTightness, Table) {
  std::printf(
      "| body | tilt (deg) | volume: polyhedron | volume: box | polyhedron / box | front: "
      "polyhedron | front: box | polyhedron / box | mean view: polyhedron | mean view: box |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n");
  const Cone cylinder{Vec3(0, -2, 0), 1.0, Vec3(0, 2, 0), 1.0, true};  // r 1, length 4
  const Sphere sphere{Vec3(0.0), 1.0};
  const Mat4 ellipsoid = glm::scale(Mat4(1.0), Vec3(1.0, 2.0, 1.0));  // 1 x 2 x 1, long axis y
  for (int deg : {0, 15, 30, 45, 60}) {
    const Mat4 tilt = glm::rotate(Mat4(1.0), glm::radians(static_cast<double>(deg)), Vec3(0, 0, 1));
    const Tightness c = measure(cylinder, tilt);
    print_row("cylinder r 1, length 4", std::to_string(deg), c);
    const Tightness e = measure(sphere, tilt * ellipsoid);
    print_row("ellipsoid 1 x 2 x 1", std::to_string(deg), e);
    // Fig. 3: tilting costs the world box, not the oriented hexahedron.
    EXPECT_NEAR(c.poly_volume, 4.0 / kPi, 1e-9);
    EXPECT_LE(c.poly_volume, c.box_volume + 1e-9);
    EXPECT_LE(c.poly_mean, c.box_mean + 1e-9);
    if (deg > 0) {
      EXPECT_LT(c.poly_volume, c.box_volume);
    }
    EXPECT_LT(e.poly_volume, e.box_volume);
  }
  // A cylinder tilted about a skew axis, and a sphere (whose box does not
  // depend on orientation).
  const Mat4 skew = glm::rotate(Mat4(1.0), glm::radians(45.0), glm::normalize(Vec3(1, 0, 1)));
  print_row("cylinder, 45 deg about (1,0,1)", "45", measure(cylinder, skew));
  // Cylinders with axes uniformly distributed over directions (seeded),
  // ratios averaged.
  std::mt19937_64 rng(5);
  Tightness mean{};
  constexpr int kOrientations = 1000;
  for (int i = 0; i < kOrientations; ++i) {
    const Vec3 axis = 2.0 * random_unit(rng);
    const Tightness t = measure(Cone{-axis, 1.0, axis, 1.0, true}, Mat4(1.0));
    mean.poly_volume += t.poly_volume / kOrientations;
    mean.box_volume += t.box_volume / kOrientations;
    mean.poly_front += t.poly_front / kOrientations;
    mean.box_front += t.box_front / kOrientations;
    mean.poly_mean += t.poly_mean / kOrientations;
    mean.box_mean += t.box_mean / kOrientations;
  }
  print_row("cylinder, random orientation (mean of 1000)", "any", mean);
  const Tightness s = measure(sphere, Mat4(1.0));
  print_row("sphere", "any", s);
  EXPECT_LT(s.poly_volume, s.box_volume);
  EXPECT_LT(s.poly_mean, s.box_mean);
}

// The face count vs tightness trade-off for the sphere (docs/bounding.md):
// tangent planes at the directions of regular and semi-regular arrangements.
TEST(BoundingTightness, SphereChoices) {
  const double phi = std::numbers::phi, iphi = 1.0 / phi;
  std::vector<Vec3> axes, diagonals, edges, dodeca_faces, icosa_faces;
  for (int a = 0; a < 3; ++a) {
    for (double s : {-1.0, 1.0}) {
      Vec3 v(0.0);
      v[a] = s;
      axes.push_back(v);
    }
  }
  for (double a : {-1.0, 1.0}) {
    for (double b : {-1.0, 1.0}) {
      for (double c : {-1.0, 1.0}) diagonals.push_back(glm::normalize(Vec3(a, b, c)));
      edges.push_back(glm::normalize(Vec3(a, b, 0)));
      edges.push_back(glm::normalize(Vec3(0, a, b)));
      edges.push_back(glm::normalize(Vec3(a, 0, b)));
      // Icosahedron vertices: the face normals of the circumscribed dodecahedron.
      dodeca_faces.push_back(glm::normalize(Vec3(0, a, b * phi)));
      dodeca_faces.push_back(glm::normalize(Vec3(a, b * phi, 0)));
      dodeca_faces.push_back(glm::normalize(Vec3(a * phi, 0, b)));
      // Dodecahedron vertices: the face normals of the circumscribed icosahedron.
      icosa_faces.push_back(glm::normalize(Vec3(0, a * iphi, b * phi)));
      icosa_faces.push_back(glm::normalize(Vec3(a * iphi, b * phi, 0)));
      icosa_faces.push_back(glm::normalize(Vec3(a * phi, 0, b * iphi)));
    }
  }
  for (const Vec3& d : diagonals) icosa_faces.push_back(d);
  auto join = [](std::vector<Vec3> a, const std::vector<Vec3>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  };
  const std::vector<std::pair<const char*, std::vector<Vec3>>> choices = {
      {"cube", axes},
      {"octahedron", diagonals},
      {"rhombic dodecahedron", edges},
      {"dodecahedron", dodeca_faces},
      {"cube + octahedron", join(axes, diagonals)},
      {"cube + rhombic dodecahedron", join(axes, edges)},
      {"icosahedron (chosen)", icosa_faces},
      {"cube + octahedron + rhombic dodecahedron", join(join(axes, diagonals), edges)},
      {"dodecahedron + icosahedron", join(dodeca_faces, icosa_faces)},
  };
  std::printf(
      "| polyhedron | faces | vertices | edges | volume / sphere = mean shadow / disk | worst "
      "shadow / disk |\n|---|---|---|---|---|---|\n");
  const std::vector<Vec3> dirs = view_directions(20000);
  for (const auto& [name, normals] : choices) {
    const auto p = circumscribed_polyhedron(normals);
    ASSERT_TRUE(p) << name;
    expect_valid_polyhedron(*p);
    EXPECT_EQ(p->faces.size(), normals.size()) << name;
    size_t edge_count = 0;
    for (const auto& f : p->faces) edge_count += f.size();
    double worst = 0;
    for (const Vec3& d : dirs) worst = std::max(worst, projected_area(*p, d) / kPi);
    std::printf("| %s | %zu | %zu | %zu | %.3f | %.3f |\n", name, p->faces.size(),
                p->vertices.size(), edge_count / 2, volume(*p) / (4.0 / 3.0 * kPi), worst);
  }
}

}  // namespace
}  // namespace locus
