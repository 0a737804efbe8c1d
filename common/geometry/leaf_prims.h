// The ray walk's copy of the scene's simplest primitives, laid out in the
// hierarchy's leaf order (Bvh::order): a leaf's primitives lie side by
// side, each in under two cache lines, where the PrimitiveSet keeps one in
// three places (its PrimRef; its PolygonPrim, TrianglePrim, SpherePrim or
// ConePrim; a polygon's vertices) and reaches them through a switch on the
// kind. The tests are the PrimitiveSet's own arithmetic (plane_crossing and
// edge_flips, triangle_crossing, sphere_roots, intersect_cone), so every
// answer is the same bit for bit (docs/renderer.md, "The ray kernel against
// Embree").
#pragma once

#include <cstdint>
#include <vector>

#include "common/geometry/bvh.h"
#include "common/geometry/geometry.h"

namespace locus {

// Polygons of up to this many vertices are copied (triangles and quads:
// SPD tetra, mount, sombrero).
inline constexpr int kLeafPolygonMax = 4;

enum class LeafKind : uint8_t {
  kOther,     // tested through the PrimitiveSet
  kPolygon,   // a PolygonPrim of at most kLeafPolygonMax vertices
  kTriangle,  // a TrianglePrim
  kSphere,    // a SpherePrim whose frame is the identity
  kCone,      // a ConePrim whose frame is the identity
};

struct LeafPolygonData {
  Vec3 normal;
  double offset;
  Vec2 pts[kLeafPolygonMax];
};
struct LeafTriangleData {
  Vec3 p0, e1, e2, normal;
};
struct LeafSphereData {
  Vec3 center;
  double radius;
};
struct LeafConeData {
  Cone c;
  ConeAxis axis;
};

struct LeafPrim {
  LeafKind kind = LeafKind::kOther;
  int8_t n = 0, axis_u = 0, axis_v = 0;  // a polygon's vertices and axes
  uint8_t stops_light = 0;               // PreparedScene::stops_light
  int object = -1;                       // its scene object (Crossing::leaf)
  int index = -1;                        // a triangle's, in PrimitiveSet::triangles (Crossing::tri)
  union {
    LeafPolygonData polygon;
    LeafTriangleData triangle;
    LeafSphereData sphere;
    LeafConeData cone;
  };
  LeafPrim() : polygon{} {}
};

// intersect_nearest's answer for the primitive p copies: its nearest
// crossing in (tmin, tmax), with leaf (and a triangle's tri, u, v) set.
// Always inlined: GCC left it a call, which cost 2-10% of render CPU on
// SPD balls, tetra, teapot and rings (raytrace --spp 1).
[[gnu::always_inline]] inline bool leaf_nearest(const LeafPrim& p, const Ray& ray, double tmin,
                                                double tmax, Crossing* c) {
  switch (p.kind) {
    case LeafKind::kPolygon: {
      double t;
      Vec3 x;
      if (!plane_crossing(p.polygon.normal, p.polygon.offset, ray, tmin, tmax, &t, &x))
        return false;
      const double px = x[p.axis_u], py = x[p.axis_v];
      bool inside = false;
      for (int i = 0, j = p.n - 1; i < p.n; j = i++)
        inside ^= edge_flips(p.polygon.pts[i], p.polygon.pts[j], px, py);
      if (!inside) return false;
      *c = Crossing{t, p.polygon.normal};
      break;
    }
    case LeafKind::kTriangle: {
      double t, u, v;
      const LeafTriangleData& tr = p.triangle;
      if (!triangle_crossing(tr.p0, tr.e1, tr.e2, ray, tmin, tmax, &t, &u, &v)) return false;
      *c = Crossing{t, tr.normal};
      c->u = u;
      c->v = v;
      c->tri = p.index;
      break;
    }
    case LeafKind::kSphere: {
      double t0, t1;
      if (!sphere_roots(p.sphere.center, p.sphere.radius, ray, &t0, &t1)) return false;
      const double t = t0 > tmin && t0 < tmax ? t0 : t1;
      if (!(t > tmin && t < tmax)) return false;
      *c = Crossing{t, (ray.origin + t * ray.dir - p.sphere.center) / p.sphere.radius};
      break;
    }
    case LeafKind::kCone: {
      // Crossings in increasing t: the first is the nearest.
      Crossing cs[4];
      if (intersect_cone(p.cone.c, p.cone.axis, ray, tmin, tmax, cs) == 0) return false;
      *c = cs[0];
      break;
    }
    case LeafKind::kOther:
      return false;
  }
  c->leaf = p.object;
  return true;
}

// intersect_any's answer for the primitive p copies.
inline bool leaf_any(const LeafPrim& p, const Ray& ray, double tmin, double tmax) {
  if (p.kind == LeafKind::kSphere) {
    double t0, t1;
    if (!sphere_roots(p.sphere.center, p.sphere.radius, ray, &t0, &t1)) return false;
    return (t0 > tmin && t0 < tmax) || (t1 > tmin && t1 < tmax);
  }
  if (p.kind == LeafKind::kCone)
    return intersect_cone(p.cone.c, p.cone.axis, ray, tmin, tmax, nullptr) > 0;
  Crossing c;
  return leaf_nearest(p, ray, tmin, tmax, &c);
}

// One LeafPrim per slot of bvh.order (kOther where the primitive is of
// another kind), or nothing where the scene has none of these kinds.
// `stops_light` is per primitive.
std::vector<LeafPrim> build_leaf_prims(const PrimitiveSet& set, const Bvh& bvh,
                                       const std::vector<uint8_t>& stops_light);

}  // namespace locus
