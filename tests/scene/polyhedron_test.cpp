// Convex polyhedron builders (common/scene/polyhedron.cpp): boxes, prisms and
// hulls come out convex, closed, with every face counter-clockwise seen
// from outside.
#include "common/scene/polyhedron.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "common/scene/validate.h"

namespace locus {
namespace {

Vec3 face_normal(const Polyhedron& p, const std::vector<int>& face) {
  Vec3 n(0.0);  // Newell
  for (size_t i = 0; i < face.size(); ++i) {
    const Vec3& a = p.vertices[face[i]];
    const Vec3& b = p.vertices[face[(i + 1) % face.size()]];
    n += glm::cross(a, b);
  }
  return glm::normalize(n);
}

Vec3 centroid(const std::vector<Vec3>& points) {
  Vec3 c(0.0);
  for (const Vec3& p : points) c += p;
  return c / static_cast<double>(points.size());
}

// Every face points away from the interior and has all vertices behind it,
// the validator agrees, and V - E + F = 2.
void expect_convex_outward(const Polyhedron& p, double tolerance = 1e-9) {
  const Vec3 inside = centroid(p.vertices);
  for (size_t f = 0; f < p.faces.size(); ++f) {
    SCOPED_TRACE("face " + std::to_string(f));
    const Vec3 n = face_normal(p, p.faces[f]);
    const double d = glm::dot(n, p.vertices[p.faces[f][0]]);
    EXPECT_GT(d - glm::dot(n, inside), 0.0) << "face points inward";
    for (const Vec3& v : p.vertices) EXPECT_LE(glm::dot(n, v) - d, tolerance);
  }
  for (const Problem& problem : check_shape(p))
    ADD_FAILURE() << problem.field << " " << problem.what;
  size_t edges = 0;
  for (const auto& f : p.faces) edges += f.size();
  EXPECT_EQ(static_cast<long>(p.vertices.size()) - static_cast<long>(edges / 2) +
                static_cast<long>(p.faces.size()),
            2);
}

TEST(Polyhedron, Box) {
  const Polyhedron box = make_box(Vec3(-1, 0, 2), Vec3(1, 3, 2.5));
  EXPECT_EQ(box.vertices.size(), 8u);
  ASSERT_EQ(box.faces.size(), 6u);
  expect_convex_outward(box);
  // Corners given the wrong way round make the same box.
  const Polyhedron swapped = make_box(Vec3(1, 3, 2.5), Vec3(-1, 0, 2));
  EXPECT_EQ(swapped.vertices, box.vertices);
}

TEST(Polyhedron, PrismHasTwoMoreFacesThanSides) {
  for (int sides : {3, 4, 5, 6, 8, 17, 64}) {
    SCOPED_TRACE("sides " + std::to_string(sides));
    const Polyhedron p = make_prism(sides, 0.5, Vec3(1, 2, 3), Vec3(2, 4, 1), 15.0);
    EXPECT_EQ(p.vertices.size(), 2u * sides);
    EXPECT_EQ(p.faces.size(), static_cast<size_t>(sides) + 2);
    expect_convex_outward(p);
    for (const Vec3& v : p.vertices) {
      // Every vertex on the circumscribed cylinder of radius 0.5.
      const Vec3 axis = glm::normalize(Vec3(1, 2, -2));
      const Vec3 r = v - Vec3(1, 2, 3);
      EXPECT_NEAR(glm::length(r - glm::dot(r, axis) * axis), 0.5, 1e-12);
    }
  }
}

TEST(Polyhedron, PrismTwistTurnsTheFirstVertex) {
  const Polyhedron a = make_prism(4, 1, Vec3(0.0), Vec3(0, 0, 1), 0);
  const Polyhedron b = make_prism(4, 1, Vec3(0.0), Vec3(0, 0, 1), 90);
  EXPECT_NEAR(glm::length(a.vertices[1] - b.vertices[0]), 0.0, 1e-12);
}

TEST(Polyhedron, HullOfACubeWithInteriorAndSurfacePoints) {
  std::vector<Vec3> points;
  for (int i = 0; i < 8; ++i) points.emplace_back(i & 1, (i >> 1) & 1, (i >> 2) & 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 200; ++i) points.emplace_back(u(rng), u(rng), u(rng));  // inside
  for (int i = 0; i < 50; ++i) points.emplace_back(u(rng), u(rng), 1.0);      // on the top
  for (int i = 0; i < 20; ++i) points.emplace_back(u(rng), 0.0, 0.0);         // on an edge
  points.emplace_back(0.5, 0.5, 0.5);
  points.push_back(points[3]);  // a repeated corner
  std::shuffle(points.begin(), points.end(), rng);

  const std::optional<Polyhedron> hull = make_hull(points);
  ASSERT_TRUE(hull);
  EXPECT_EQ(hull->faces.size(), 6u);
  EXPECT_EQ(hull->vertices.size(), 8u);
  for (const auto& f : hull->faces) EXPECT_EQ(f.size(), 4u);
  expect_convex_outward(*hull);
}

TEST(Polyhedron, HullOfALattice) {
  // 6 x 6 x 6 grid points: every point but the corners is on a face, an
  // edge or inside, the most degenerate input for an incremental hull.
  std::vector<Vec3> points;
  for (int x = 0; x < 6; ++x) {
    for (int y = 0; y < 6; ++y) {
      for (int z = 0; z < 6; ++z) points.emplace_back(x * 0.2, y * 0.3, z * 0.1);
    }
  }
  const std::optional<Polyhedron> hull = make_hull(points);
  ASSERT_TRUE(hull);
  EXPECT_EQ(hull->faces.size(), 6u);
  EXPECT_EQ(hull->vertices.size(), 8u);
  expect_convex_outward(*hull);
}

TEST(Polyhedron, HullOfAPrismRecoversItsFaces) {
  const Polyhedron prism = make_prism(7, 2.0, Vec3(0.0), Vec3(0, 3, 0));
  const std::optional<Polyhedron> hull = make_hull(prism.vertices);
  ASSERT_TRUE(hull);
  EXPECT_EQ(hull->faces.size(), 9u);
  EXPECT_EQ(hull->vertices.size(), 14u);
  expect_convex_outward(*hull);
}

TEST(Polyhedron, HullOfTetrahedronAndOctahedron) {
  std::optional<Polyhedron> t =
      make_hull({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1), Vec3(0.1, 0.1, 0.1)});
  ASSERT_TRUE(t);
  EXPECT_EQ(t->faces.size(), 4u);
  EXPECT_EQ(t->vertices.size(), 4u);
  expect_convex_outward(*t);
  std::optional<Polyhedron> o =
      make_hull({Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1),
                 Vec3(0, 0, -1), Vec3(0, 0, 0)});
  ASSERT_TRUE(o);
  EXPECT_EQ(o->faces.size(), 8u);
  expect_convex_outward(*o);
}

// Seeded property test: random points, sometimes rounded onto a coarse grid
// to provoke coplanar and collinear cases.
TEST(Polyhedron, RandomHullsContainEveryPoint) {
  for (unsigned seed = 1; seed <= 60; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const int n = 4 + static_cast<int>(rng() % 300);
    const bool grid = seed % 3 == 0;
    const bool sphere = seed % 3 == 1;
    const Vec3 offset(100 * u(rng), 100 * u(rng), 100 * u(rng));
    std::vector<Vec3> points;
    for (int i = 0; i < n; ++i) {
      Vec3 p(u(rng), u(rng), u(rng));
      if (grid) p = glm::round(p * 3.0) / 3.0;
      if (sphere) p = glm::normalize(p);
      points.push_back(p + offset);
    }
    const std::optional<Polyhedron> hull = make_hull(points);
    ASSERT_TRUE(hull);
    // Points within 1e-10 of the coordinates' scale count as on a plane.
    expect_convex_outward(*hull, 1e-6);
    for (size_t f = 0; f < hull->faces.size(); ++f) {
      const Vec3 normal = face_normal(*hull, hull->faces[f]);
      const double d = glm::dot(normal, hull->vertices[hull->faces[f][0]]);
      for (const Vec3& p : points) ASSERT_LE(glm::dot(normal, p) - d, 1e-6);
    }
  }
}

TEST(Polyhedron, HullOfTheLargestAcceptedPointSet) {
  std::mt19937 rng(11);
  std::normal_distribution<double> g;
  std::vector<Vec3> points;
  for (int i = 0; i < kMaxHullVertices; ++i)
    points.push_back(glm::normalize(Vec3(g(rng), g(rng), g(rng))));
  const std::optional<Polyhedron> hull = make_hull(points);
  ASSERT_TRUE(hull);
  EXPECT_EQ(hull->vertices.size(), points.size());  // all on the sphere: all corners
  expect_convex_outward(*hull, 1e-9);
}

TEST(Polyhedron, HullOfFlatOrTooFewPointsIsNullopt) {
  EXPECT_FALSE(make_hull({}));
  EXPECT_FALSE(make_hull({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}));
  EXPECT_FALSE(
      make_hull({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0), Vec3(0.5, 0.2, 0)}));
  EXPECT_FALSE(make_hull({Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2), Vec3(3, 3, 3)}));
  EXPECT_FALSE(make_hull({Vec3(1, 1, 1), Vec3(1, 1, 1), Vec3(1, 1, 1), Vec3(1, 1, 1)}));
  EXPECT_FALSE(make_hull({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, NAN)}));
}

TEST(Polyhedron, ValidatorRejectsAnInsideOutBox) {
  Polyhedron box = make_box(Vec3(0.0), Vec3(1.0));
  for (auto& f : box.faces) std::reverse(f.begin(), f.end());
  const Problems problems = check_shape(box);
  ASSERT_FALSE(problems.empty());
  EXPECT_NE(problems[0].what.find("lies outside this face's plane"), std::string::npos);
}

}  // namespace
}  // namespace locus
