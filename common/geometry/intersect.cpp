// Exact ray intersections of the primitives (geometry.h): each kind's
// crossing test, CSG evaluation as interval arithmetic along the ray, and the
// per-primitive entry points (all crossings, any crossing, the nearest). The
// primitives are built in primitives.cpp.
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/geometry/geometry.h"

namespace locus {
namespace {

Ray to_object(const QuadricFrame& f, const Ray& ray) {
  if (f.identity) return ray;
  return Ray{transform_point(f.object_from_world, ray.origin),
             transform_vector(f.object_from_world, ray.dir)};
}

int finish_quadric(const QuadricFrame& f, int n, Crossing* c) {
  if (!f.identity) {
    for (int i = 0; i < n; ++i) c[i].normal = glm::normalize(f.normal_to_world * c[i].normal);
  }
  return n;
}

int intersect_convex(const ConvexPrim& p, const Ray& ray, double tmin, double tmax, Crossing* out) {
  double tin = -kInf, tout = kInf;
  int fin = -1, fout = -1;
  for (size_t i = 0; i < p.normals.size(); ++i) {
    const double denom = glm::dot(p.normals[i], ray.dir);
    const double dist = p.offsets[i] - glm::dot(p.normals[i], ray.origin);
    if (denom == 0.0) {
      if (dist < 0.0) return 0;  // parallel and outside this face's plane
      continue;
    }
    const double t = dist / denom;
    if (denom < 0.0) {
      if (t > tin) tin = t, fin = static_cast<int>(i);
    } else {
      if (t < tout) tout = t, fout = static_cast<int>(i);
    }
  }
  if (!(tin < tout) || fin < 0 || fout < 0) return 0;
  int n = 0;
  if (tin > tmin && tin < tmax) out[n++] = Crossing{tin, p.normals[fin]};
  if (tout > tmin && tout < tmax) out[n++] = Crossing{tout, p.normals[fout]};
  return n;
}

int intersect_polygon(const PolygonPrim& p, const Ray& ray, double tmin, double tmax,
                      Crossing* out) {
  double t;
  Vec3 x;
  if (!plane_crossing(p.normal, p.offset, ray, tmin, tmax, &t, &x)) return 0;
  const double px = x[p.axis_u], py = x[p.axis_v];
  bool inside = false;
  if (!p.bucket_first.empty()) {
    // Only the edges that can straddle py (geometry.h, PolygonPrim).
    const int k = p.bucket_of(py);
    for (int e = p.bucket_first[k]; e < p.bucket_first[k + 1]; ++e)
      inside ^= edge_flips(p.edges[e].a, p.edges[e].b, px, py);
  } else {
    const size_t n = p.pts.size();
    for (size_t i = 0, j = n - 1; i < n; j = i++) inside ^= edge_flips(p.pts[i], p.pts[j], px, py);
  }
  if (!inside) return 0;
  out[0] = Crossing{t, p.normal};
  return 1;
}

// Moller-Trumbore (triangle_crossing).
int intersect_triangle(const TrianglePrim& tr, const Ray& ray, double tmin, double tmax,
                       Crossing* out) {
  double t, u, v;
  if (!triangle_crossing(tr.p0, tr.e1, tr.e2, ray, tmin, tmax, &t, &u, &v)) return 0;
  Crossing c{t, tr.normal};
  c.u = u;
  c.v = v;
  out[0] = c;
  return 1;
}

// ---- CSG: interval arithmetic along the ray ----

struct Bound {
  double t;
  Vec3 normal;
  int leaf;
};
struct Interval {
  Bound in, out;
};

std::vector<Interval> leaf_intervals(const PrimitiveSet& set, const CsgNode& node, const Ray& ray) {
  Crossing c[4];
  int n = 0;
  switch (node.kind) {
    case PrimKind::kSphere: {
      const SpherePrim& s = set.spheres[node.index];
      n = finish_quadric(s.frame, intersect_sphere(s.s, to_object(s.frame, ray), -kInf, kInf, c),
                         c);
      break;
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[node.index];
      n = finish_quadric(s.frame,
                         intersect_cone(s.c, s.axis, to_object(s.frame, ray), -kInf, kInf, c), c);
      break;
    }
    case PrimKind::kConvex:
      n = intersect_convex(set.convexes[node.index], ray, -kInf, kInf, c);
      break;
    default:
      break;
  }
  // Leaves are convex: the first and last crossings bound the one interval.
  if (n < 2 || !(c[n - 1].t > c[0].t)) return {};
  return {Interval{Bound{c[0].t, c[0].normal, node.object},
                   Bound{c[n - 1].t, c[n - 1].normal, node.object}}};
}

std::vector<Interval> combine(const std::vector<Interval>& a, const std::vector<Interval>& b,
                              CsgOp op) {
  struct Event {
    double t;
    bool from_b;
    bool entry;
    const Bound* bound;
  };
  std::vector<Event> ev;
  ev.reserve(2 * (a.size() + b.size()));
  for (const auto& i : a) {
    ev.push_back({i.in.t, false, true, &i.in});
    ev.push_back({i.out.t, false, false, &i.out});
  }
  for (const auto& i : b) {
    ev.push_back({i.in.t, true, true, &i.in});
    ev.push_back({i.out.t, true, false, &i.out});
  }
  std::stable_sort(ev.begin(), ev.end(), [](const Event& x, const Event& y) { return x.t < y.t; });
  auto inside = [op](bool ia, bool ib) {
    switch (op) {
      case CsgOp::kUnion:
        return ia || ib;
      case CsgOp::kIntersection:
        return ia && ib;
      case CsgOp::kDifference:
        return ia && !ib;
    }
    return false;
  };
  std::vector<Interval> result;
  bool ia = false, ib = false, was = false;
  Bound start{};
  for (const Event& e : ev) {
    (e.from_b ? ib : ia) = e.entry;
    const bool now = inside(ia, ib);
    if (now == was) continue;
    Bound bound = *e.bound;
    // The subtracted body's surface faces the other way in a difference.
    if (op == CsgOp::kDifference && e.from_b) bound.normal = -bound.normal;
    if (now) {
      start = bound;
    } else if (bound.t > start.t) {
      result.push_back(Interval{start, bound});
    }
    was = now;
  }
  return result;
}

std::vector<Interval> csg_intervals(const PrimitiveSet& set, const CsgPrim& csg, int node,
                                    const Ray& ray) {
  const CsgNode& n = csg.nodes[node];
  if (n.leaf) return leaf_intervals(set, n, ray);
  const auto left = csg_intervals(set, csg, n.left, ray);
  if (left.empty() && n.op != CsgOp::kUnion) return {};
  return combine(left, csg_intervals(set, csg, n.right, ray), n.op);
}

}  // namespace

int intersect_sphere(const Sphere& s, const Ray& ray, double tmin, double tmax, Crossing* out) {
  double t0, t1;
  if (!sphere_roots(s.center, s.radius, ray, &t0, &t1)) return 0;
  int n = 0;
  for (double t : {t0, t1}) {
    if (t > tmin && t < tmax) {
      out[n++] = Crossing{t, (ray.origin + t * ray.dir - s.center) / s.radius};
    }
  }
  return n;
}

int intersect_cone(const Cone& c, const Ray& ray, double tmin, double tmax, Crossing* out) {
  return intersect_cone(c, cone_axis(c), ray, tmin, tmax, out);
}

// Cylinder/cone/frustum side: |q|^2 = (r0 + k s)^2 with s the axial
// coordinate and q the radial vector; caps are disks.
int intersect_cone(const Cone& c, const ConeAxis& ax, const Ray& ray, double tmin, double tmax,
                   Crossing* out) {
  const double h = ax.h;
  const Vec3& a = ax.a;
  const double k = ax.k;
  const Vec3 co = ray.origin - c.base;
  const double da = glm::dot(ray.dir, a), ca = glm::dot(co, a);
  const Vec3 dp = ray.dir - da * a, cp = co - ca * a;
  const double rc = c.base_radius + k * ca;
  int n = 0;
  double t0, t1;
  if (solve_quadratic(glm::dot(dp, dp) - k * k * da * da, 2.0 * (glm::dot(cp, dp) - k * rc * da),
                      glm::dot(cp, cp) - rc * rc, &t0, &t1)) {
    for (double t : {t0, t0 == t1 ? kInf : t1}) {
      if (!(t > tmin && t < tmax)) continue;
      const double s = ca + t * da;
      if (s < 0.0 || s > h) continue;
      const Vec3 q = cp + t * dp;
      const double r = c.base_radius + k * s;
      const Vec3 g = q - r * k * a;
      if (!out) {  // counting only (intersect_any)
        if (glm::dot(g, g) > 0) ++n;
        continue;
      }
      const double len = glm::length(g);
      if (!(len > 0)) continue;  // the apex point itself
      out[n++] = Crossing{t, g / len};
    }
  }
  if (c.capped && da != 0.0) {
    struct Cap {
      double s, r;
      Vec3 normal;
    };
    for (const Cap& cap : {Cap{0.0, c.base_radius, -a}, Cap{h, c.apex_radius, a}}) {
      if (cap.r <= 0.0) continue;
      const double t = (cap.s - ca) / da;
      if (!(t > tmin && t < tmax)) continue;
      const Vec3 q = cp + t * dp;
      if (glm::dot(q, q) <= cap.r * cap.r) {
        if (out) out[n] = Crossing{t, cap.normal};
        ++n;
      }
    }
  }
  if (out) std::sort(out, out + n, [](const Crossing& x, const Crossing& y) { return x.t < y.t; });
  return n;
}

namespace {

// The primitives bounded by planes: convex polyhedra, polygons, triangles.
int intersect_flat(const PrimitiveSet& set, const PrimRef& ref, const Ray& ray, double tmin,
                   double tmax, Crossing* c) {
  switch (ref.kind) {
    case PrimKind::kConvex:
      return intersect_convex(set.convexes[ref.index], ray, tmin, tmax, c);
    case PrimKind::kPolygon:
      return intersect_polygon(set.polygons[ref.index], ray, tmin, tmax, c);
    case PrimKind::kTriangle: {
      const int n = intersect_triangle(set.triangles[ref.index], ray, tmin, tmax, c);
      if (n) c[0].tri = ref.index;
      return n;
    }
    default:
      return 0;
  }
}

}  // namespace

bool intersect_any(const PrimitiveSet& set, int prim, const Ray& ray, double tmin, double tmax) {
  const PrimRef& ref = set.prims[prim];
  switch (ref.kind) {
    case PrimKind::kSphere: {
      const SpherePrim& s = set.spheres[ref.index];
      double t0, t1;
      if (!sphere_roots(s.s.center, s.s.radius, to_object(s.frame, ray), &t0, &t1)) return false;
      return (t0 > tmin && t0 < tmax) || (t1 > tmin && t1 < tmax);
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[ref.index];
      return intersect_cone(s.c, s.axis, to_object(s.frame, ray), tmin, tmax, nullptr) > 0;
    }
    case PrimKind::kConvex:
    case PrimKind::kPolygon:
    case PrimKind::kTriangle: {
      Crossing c[4];
      return intersect_flat(set, ref, ray, tmin, tmax, c) > 0;
    }
    default: {
      thread_local std::vector<Crossing> scratch;
      scratch.clear();
      return intersect_all(set, prim, ray, tmin, tmax, scratch) > 0;
    }
  }
}

int intersect_all(const PrimitiveSet& set, int prim, const Ray& ray, double tmin, double tmax,
                  std::vector<Crossing>& out) {
  const PrimRef& ref = set.prims[prim];
  Crossing c[4];
  int n = 0;
  switch (ref.kind) {
    case PrimKind::kSphere: {
      const SpherePrim& s = set.spheres[ref.index];
      n = finish_quadric(s.frame, intersect_sphere(s.s, to_object(s.frame, ray), tmin, tmax, c), c);
      break;
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[ref.index];
      n = finish_quadric(s.frame,
                         intersect_cone(s.c, s.axis, to_object(s.frame, ray), tmin, tmax, c), c);
      break;
    }
    case PrimKind::kConvex:
    case PrimKind::kPolygon:
    case PrimKind::kTriangle:
      n = intersect_flat(set, ref, ray, tmin, tmax, c);
      break;
    case PrimKind::kCsg: {
      const auto iv = csg_intervals(set, set.csgs[ref.index], 0, ray);
      int added = 0;
      for (const Interval& i : iv) {
        for (const Bound* b : {&i.in, &i.out}) {
          if (b->t > tmin && b->t < tmax) {
            Crossing x{b->t, b->normal};
            x.leaf = b->leaf;
            out.push_back(x);
            ++added;
          }
        }
      }
      return added;
    }
  }
  for (int i = 0; i < n; ++i) {
    if (c[i].leaf < 0) c[i].leaf = ref.object;
    out.push_back(c[i]);
  }
  return n;
}

std::optional<Crossing> intersect_nearest(const PrimitiveSet& set, int prim, const Ray& ray,
                                          double tmin, double tmax) {
  const PrimRef& ref = set.prims[prim];
  Crossing c[4];
  int n = 0;
  switch (ref.kind) {
    case PrimKind::kConvex:
    case PrimKind::kPolygon:
    case PrimKind::kTriangle:
      n = intersect_flat(set, ref, ray, tmin, tmax, c);
      break;
    // Quadrics list their crossings in increasing t: only the first one's
    // normal is carried to world space.
    case PrimKind::kSphere: {
      const SpherePrim& s = set.spheres[ref.index];
      n = intersect_sphere(s.s, to_object(s.frame, ray), tmin, tmax, c);
      if (n) finish_quadric(s.frame, 1, c);
      break;
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[ref.index];
      n = intersect_cone(s.c, s.axis, to_object(s.frame, ray), tmin, tmax, c);
      if (n) finish_quadric(s.frame, 1, c);
      break;
    }
    default: {
      thread_local std::vector<Crossing> buf;
      buf.clear();
      if (!intersect_all(set, prim, ray, tmin, tmax, buf)) return std::nullopt;
      return buf.front();
    }
  }
  if (!n) return std::nullopt;
  c[0].leaf = ref.object;
  return c[0];
}

Vec3 shading_normal(const PrimitiveSet& set, const PrimRef& ref, const Crossing& c) {
  if (has_vertex_normals(set, ref)) {
    const TrianglePrim& tr = set.triangles[ref.index];
    const Vec3 n = (1.0 - c.u - c.v) * tr.n0 + c.u * tr.n1 + c.v * tr.n2;
    const double len = glm::length(n);
    if (len > 0) return n / len;
  }
  return c.normal;
}

}  // namespace locus
