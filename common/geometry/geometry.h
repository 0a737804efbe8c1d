// Exact ray intersection of every primitive (scene.h shapes, flattened into
// world-space primitives) and of CSG trees. Two phases, as in pbrt: a cheap
// crossing record per primitive, and the full surface record for the winner.
// One header for both halves: primitives.cpp builds the set from a scene
// (build_primitives: frames, bounds, CSG trees as node arrays);
// intersect.cpp intersects a ray with them (intersect_all / _any / _nearest,
// CSG evaluation, shading_normal).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "common/base/math.h"
#include "common/scene/scene.h"

namespace locus {

struct Ray {
  Vec3 origin;
  Vec3 dir;  // unit length for eye and secondary rays; any length for segments
};

struct Aabb {
  Vec3 lo{1e300, 1e300, 1e300};
  Vec3 hi{-1e300, -1e300, -1e300};
  void extend(const Vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  void extend(const Aabb& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  bool empty() const { return lo.x > hi.x; }
  Vec3 centre() const { return 0.5 * (lo + hi); }
  double area() const {
    if (empty()) return 0.0;
    const Vec3 e = hi - lo;
    return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
};

// One crossing of a ray with a primitive's surface. `normal` is the outward
// geometric normal (world space, unit): SHADING.md "Entering or leaving".
// `leaf` identifies the scene object whose surface was crossed (for CSG, the
// operand), `u, v` are barycentrics on triangles (for normal interpolation).
struct Crossing {
  double t = 0;
  Vec3 normal{0, 0, 1};
  int leaf = -1;
  int tri = -1;
  double u = 0, v = 0;
};

// ---- World-space primitives ----

// Quadrics are intersected in object space: the ray is mapped by
// object_from_world (t is preserved because the direction is not
// renormalised) and normals go back by the inverse transpose.
struct QuadricFrame {
  bool identity = true;
  Mat4 object_from_world{1.0};
  glm::dmat3 normal_to_world{1.0};
};

struct SpherePrim {
  Sphere s;
  QuadricFrame frame;
};

// A cone's axis, prepared once: unit direction, length, radius slope.
struct ConeAxis {
  Vec3 a{0, 0, 1};
  double h = 1, k = 0;
};
ConeAxis cone_axis(const Cone& c);

struct ConePrim {
  Cone c;
  QuadricFrame frame;
  ConeAxis axis;
};

// Convex polyhedron as half-spaces n . x <= d (n outward, unit).
struct ConvexPrim {
  std::vector<Vec3> normals;
  std::vector<double> offsets;
  std::vector<std::vector<Vec3>> faces;  // world-space outlines, for the scanline pass
};

// Planar polygon (convex or concave): plane, and the vertices projected on
// the two axes that drop the normal's dominant one (crossing test).
struct PolygonPrim {
  Vec3 normal;  // front (CCW) side
  double offset;
  int axis_u, axis_v;
  std::vector<Vec2> pts;
  std::vector<Vec3> verts;  // world space, for the scanline pass
  // Polygons of more than kPolygonBucketAbove vertices (SPD gears' faces:
  // 144) keep their edges bucketed by their extent along axis_v: the
  // crossing test's line through a point meets only edges of the point's
  // bucket, so it walks those instead of every edge, with the same
  // arithmetic per edge (the same answer, bit for bit). Edge k of bucket b
  // is edges[bucket_first[b] + k]: (pts[i], pts[i - 1]), as the test pairs them.
  struct Edge {
    Vec2 a, b;
  };
  std::vector<Edge> edges;
  std::vector<int> bucket_first;  // bucket count + 1 offsets; empty: no buckets
  double v_lo = 0, v_scale = 0;   // bucket of v: floor((v - v_lo) * v_scale), clamped
  int bucket_of(double v) const {
    return clamped_floor((v - v_lo) * v_scale, 0, static_cast<int>(bucket_first.size()) - 2);
  }
};
inline constexpr int kPolygonBucketAbove = 8;

// Where the ray meets the plane n . x = offset for t in (tmin, tmax), and
// the point there: false where it does not (or runs parallel). The first
// half of every polygon test (intersect_polygon, leaf_nearest).
inline bool plane_crossing(const Vec3& n, double offset, const Ray& ray, double tmin, double tmax,
                           double* t, Vec3* x) {
  const double denom = glm::dot(n, ray.dir);
  if (denom == 0.0) return false;
  *t = (offset - glm::dot(n, ray.origin)) / denom;
  if (!(*t > tmin && *t < tmax)) return false;
  *x = ray.origin + *t * ray.dir;
  return true;
}

// Moller-Trumbore: does the ray cross the triangle (p0, p0 + e1, p0 + e2)
// for some t in (tmin, tmax)? Where it does: t and the barycentric u, v.
inline bool triangle_crossing(const Vec3& p0, const Vec3& e1, const Vec3& e2, const Ray& ray,
                              double tmin, double tmax, double* t, double* u, double* v) {
  const Vec3 pv = glm::cross(ray.dir, e2);
  const double det = glm::dot(e1, pv);
  if (det == 0.0) return false;
  const double inv = 1.0 / det;
  const Vec3 tv = ray.origin - p0;
  *u = glm::dot(tv, pv) * inv;
  if (*u < 0.0 || *u > 1.0) return false;
  const Vec3 qv = glm::cross(tv, e1);
  *v = glm::dot(ray.dir, qv) * inv;
  if (*v < 0.0 || *u + *v > 1.0) return false;
  *t = glm::dot(e2, qv) * inv;
  return *t > tmin && *t < tmax;
}

// Where the ray meets the sphere's surface, t0 <= t1; false where it
// misses it.
inline bool sphere_roots(const Vec3& center, double radius, const Ray& ray, double* t0,
                         double* t1) {
  const Vec3 oc = ray.origin - center;
  return solve_quadratic(glm::dot(ray.dir, ray.dir), 2.0 * glm::dot(oc, ray.dir),
                         glm::dot(oc, oc) - radius * radius, t0, t1);
}

// The even-odd crossing test's step for edge (a, b) and the point (px, py)
// of the polygon's plane dropped on its two axes: true where the edge
// crosses the line v = py right of the point (each such edge flips
// inside/outside). Correct for concave polygons (SPD gears).
inline bool edge_flips(const Vec2& a, const Vec2& b, double px, double py) {
  if ((a.y > py) == (b.y > py)) return false;
  const double xc = a.x + (py - a.y) * (b.x - a.x) / (b.y - a.y);
  return px < xc;
}

// A triangle of a mesh or of a patch's fan; n0..n2 are vertex normals when
// has_normals.
struct TrianglePrim {
  Vec3 p0, e1, e2;
  Vec3 normal;  // geometric, by winding (CCW front)
  bool has_normals = false;
  Vec3 n0, n1, n2;
};

struct CsgPrim;

enum class PrimKind : uint8_t { kSphere, kCone, kConvex, kPolygon, kTriangle, kCsg };

// A CSG node compiled for intersection: leaves are convex solids (sphere,
// capped cone, polyhedron), so each gives at most one interval along a ray.
struct CsgNode {
  bool leaf = false;
  CsgOp op = CsgOp::kUnion;
  int left = -1, right = -1;  // node indices
  PrimKind kind = PrimKind::kSphere;
  int index = -1;   // into the leaf arrays of the PrimitiveSet
  int object = -1;  // scene object of a leaf
};

struct CsgPrim {
  std::vector<CsgNode> nodes;  // nodes[0] is the root
};

struct PrimRef {
  PrimKind kind;
  int index;   // into the array of that kind
  int object;  // scene object index
};

// All primitives of a scene, in world space.
struct PrimitiveSet {
  std::vector<SpherePrim> spheres;
  std::vector<ConePrim> cones;
  std::vector<ConvexPrim> convexes;
  std::vector<PolygonPrim> polygons;
  std::vector<TrianglePrim> triangles;
  std::vector<CsgPrim> csgs;
  std::vector<PrimRef> prims;  // the renderable ones (CSG operands excluded)
  std::vector<Aabb> bounds;    // per prims[i]
};

// Newell's method: the unit normal of a planar outline, convex or not, on
// the side from which it runs counter-clockwise; (0, 0, 1) if degenerate.
Vec3 newell_normal(const std::vector<Vec3>& pts);

// The outline of a polygon as intersect_all hits it: a point of the plane
// is inside when, dropped on the axes (axis_u, axis_v), it falls inside the
// vertices dropped the same way. A vertex off the plane (a bent input
// polygon) is moved onto it along the third axis; planar input is returned
// as it is, bit for bit.
std::vector<Vec3> polygon_outline(const PolygonPrim& p);
// Vertex v of the polygon as polygon_outline gives it.
Vec3 outline_point(const PolygonPrim& p, Vec3 v);

// The convex hull of 2D points by Andrew's monotone chain: indices into
// `p`, counter-clockwise, without collinear points (fewer than 3 where the
// points span no area).
std::vector<int> convex_hull_2d(const std::vector<Vec2>& p);

// Flattens the scene into primitives (transforms of polygons, meshes and
// polyhedra are applied to their vertices; quadrics keep a frame).
PrimitiveSet build_primitives(const Scene& scene);

// Every crossing of prims[i] with the ray for t in (tmin, tmax), in
// increasing t, appended to `out`. Returns the number appended.
int intersect_all(const PrimitiveSet& set, int prim, const Ray& ray, double tmin, double tmax,
                  std::vector<Crossing>& out);

// Whether prims[i] crosses the ray for some t in (tmin, tmax): the same
// crossings as intersect_all, without their normals (an opaque occluder's
// exact shadow test needs no more).
bool intersect_any(const PrimitiveSet& set, int prim, const Ray& ray, double tmin, double tmax);

// The nearest crossing of prims[i] in (tmin, tmax).
std::optional<Crossing> intersect_nearest(const PrimitiveSet& set, int prim, const Ray& ray,
                                          double tmin, double tmax);

// Does the primitive shade with interpolated vertex normals (meshes and
// patches with normals)? Else its shading normal is the geometric one.
inline bool has_vertex_normals(const PrimitiveSet& set, const PrimRef& ref) {
  return ref.kind == PrimKind::kTriangle && set.triangles[ref.index].has_normals;
}

// Shading normal at a crossing: the interpolated vertex normal where
// has_vertex_normals, else the geometric normal (not yet flipped).
Vec3 shading_normal(const PrimitiveSet& set, const PrimRef& ref, const Crossing& c);

// Object-space primitive tests, exposed for the property tests.
int intersect_sphere(const Sphere& s, const Ray& ray, double tmin, double tmax, Crossing* out);
int intersect_cone(const Cone& c, const Ray& ray, double tmin, double tmax, Crossing* out);
int intersect_cone(const Cone& c, const ConeAxis& axis, const Ray& ray, double tmin, double tmax,
                   Crossing* out);

}  // namespace locus
