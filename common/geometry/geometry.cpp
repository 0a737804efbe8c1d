#include "common/geometry/geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

int intersect_convex(const ConvexPrim& p, const Ray& ray, double tmin, double tmax,
                     Crossing* out) {
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
  const double denom = glm::dot(p.normal, ray.dir);
  if (denom == 0.0) return 0;
  const double t = (p.offset - glm::dot(p.normal, ray.origin)) / denom;
  if (!(t > tmin && t < tmax)) return 0;
  const Vec3 x = ray.origin + t * ray.dir;
  const double px = x[p.axis_u], py = x[p.axis_v];
  // Even-odd crossing test: correct for concave polygons (SPD gears).
  bool inside = false;
  const size_t n = p.pts.size();
  for (size_t i = 0, j = n - 1; i < n; j = i++) {
    const Vec2& a = p.pts[i];
    const Vec2& b = p.pts[j];
    if ((a.y > py) != (b.y > py)) {
      const double xc = a.x + (py - a.y) * (b.x - a.x) / (b.y - a.y);
      if (px < xc) inside = !inside;
    }
  }
  if (!inside) return 0;
  out[0] = Crossing{t, p.normal};
  return 1;
}

// Moller-Trumbore.
int intersect_triangle(const TrianglePrim& tr, const Ray& ray, double tmin, double tmax,
                       Crossing* out) {
  const Vec3 pv = glm::cross(ray.dir, tr.e2);
  const double det = glm::dot(tr.e1, pv);
  if (det == 0.0) return 0;
  const double inv = 1.0 / det;
  const Vec3 tv = ray.origin - tr.p0;
  const double u = glm::dot(tv, pv) * inv;
  if (u < 0.0 || u > 1.0) return 0;
  const Vec3 qv = glm::cross(tv, tr.e1);
  const double v = glm::dot(ray.dir, qv) * inv;
  if (v < 0.0 || u + v > 1.0) return 0;
  const double t = glm::dot(tr.e2, qv) * inv;
  if (!(t > tmin && t < tmax)) return 0;
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

std::vector<Interval> leaf_intervals(const PrimitiveSet& set, const CsgNode& node,
                                     const Ray& ray) {
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
      n = finish_quadric(s.frame, intersect_cone(s.c, s.axis, to_object(s.frame, ray), -kInf, kInf, c), c);
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
  for (const auto& i : a) ev.push_back({i.in.t, false, true, &i.in}), ev.push_back({i.out.t, false, false, &i.out});
  for (const auto& i : b) ev.push_back({i.in.t, true, true, &i.in}), ev.push_back({i.out.t, true, false, &i.out});
  std::stable_sort(ev.begin(), ev.end(), [](const Event& x, const Event& y) { return x.t < y.t; });
  auto inside = [op](bool ia, bool ib) {
    switch (op) {
      case CsgOp::kUnion: return ia || ib;
      case CsgOp::kIntersection: return ia && ib;
      case CsgOp::kDifference: return ia && !ib;
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

Aabb transformed_box(const Aabb& b, const QuadricFrame& f, const Mat4& world_from_object) {
  if (f.identity) return b;
  Aabb out;
  for (int i = 0; i < 8; ++i) {
    const Vec3 p((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z);
    out.extend(transform_point(world_from_object, p));
  }
  return out;
}

// Box of a disk of radius r centred at c, perpendicular to unit axis a.
void extend_disk(Aabb& b, const Vec3& c, const Vec3& a, double r) {
  const Vec3 e(r * std::sqrt(std::max(0.0, 1.0 - a.x * a.x)),
               r * std::sqrt(std::max(0.0, 1.0 - a.y * a.y)),
               r * std::sqrt(std::max(0.0, 1.0 - a.z * a.z)));
  b.extend(c - e);
  b.extend(c + e);
}

class Builder {
 public:
  explicit Builder(const Scene& scene) : scene_(scene) {}

  PrimitiveSet build() {
    const std::vector<bool> operand = csg_operand_mask(scene_);
    for (size_t i = 0; i < scene_.objects.size(); ++i) {
      if (operand[i]) continue;
      add_object(static_cast<int>(i), scene_.objects[i].world_from_object);
    }
    return std::move(set_);
  }

 private:
  QuadricFrame frame_of(const Mat4& world_from_object) {
    QuadricFrame f;
    f.identity = world_from_object == Mat4(1.0);
    if (!f.identity) {
      f.object_from_world = glm::inverse(world_from_object);
      f.normal_to_world = glm::transpose(glm::dmat3(f.object_from_world));
    }
    return f;
  }

  void push(PrimKind kind, int index, int object, const Aabb& box) {
    set_.prims.push_back(PrimRef{kind, index, object});
    set_.bounds.push_back(box);
  }

  Aabb sphere_box(const SpherePrim& s, const Mat4& xf) {
    Aabb b;
    b.extend(s.s.center - Vec3(s.s.radius));
    b.extend(s.s.center + Vec3(s.s.radius));
    return transformed_box(b, s.frame, xf);
  }

  Aabb cone_box(const ConePrim& c, const Mat4& xf) {
    Aabb b;
    const Vec3 axis = glm::normalize(c.c.apex - c.c.base);
    extend_disk(b, c.c.base, axis, c.c.base_radius);
    extend_disk(b, c.c.apex, axis, c.c.apex_radius);
    return transformed_box(b, c.frame, xf);
  }

  // Returns the index into set_.convexes and the world box.
  int add_convex(const Polyhedron& p, const Mat4& xf, Aabb* box) {
    std::vector<Vec3> w(p.vertices.size());
    Vec3 centroid(0.0);
    for (size_t i = 0; i < w.size(); ++i) {
      w[i] = transform_point(xf, p.vertices[i]);
      box->extend(w[i]);
      centroid += w[i];
    }
    centroid /= static_cast<double>(std::max<size_t>(1, w.size()));
    ConvexPrim c;
    for (const auto& face : p.faces) {
      std::vector<Vec3> pts;
      Vec3 fc(0.0);
      for (int vi : face) pts.push_back(w[vi]), fc += w[vi];
      fc /= static_cast<double>(pts.size());
      Vec3 n = newell_normal(pts);
      // Orient outward whatever the face winding was.
      if (glm::dot(n, fc - centroid) < 0) n = -n;
      c.normals.push_back(n);
      c.offsets.push_back(glm::dot(n, fc));
      c.faces.push_back(std::move(pts));
    }
    set_.convexes.push_back(std::move(c));
    return static_cast<int>(set_.convexes.size()) - 1;
  }

  // Compiles the CSG subtree rooted at scene object `obj` into `csg`;
  // returns the node index and extends `box` per the set operation.
  int add_csg_node(CsgPrim& csg, int obj, const Mat4& parent_xf, Aabb* box) {
    const Object& o = scene_.objects[obj];
    const Mat4 xf = parent_xf * o.world_from_object;
    const int id = static_cast<int>(csg.nodes.size());
    csg.nodes.emplace_back();
    CsgNode node;
    if (const auto* c = std::get_if<Csg>(&o.shape)) {
      node.op = c->op;
      Aabb lb, rb;
      node.left = add_csg_node(csg, c->left, xf, &lb);
      node.right = add_csg_node(csg, c->right, xf, &rb);
      if (c->op == CsgOp::kUnion) {
        lb.extend(rb);
      } else if (c->op == CsgOp::kIntersection) {
        lb.lo = glm::max(lb.lo, rb.lo);
        lb.hi = glm::min(lb.hi, rb.hi);
      }
      *box = lb;
    } else {
      node.leaf = true;
      node.object = obj;
      if (const auto* s = std::get_if<Sphere>(&o.shape)) {
        set_.spheres.push_back(SpherePrim{*s, frame_of(xf)});
        node.kind = PrimKind::kSphere;
        node.index = static_cast<int>(set_.spheres.size()) - 1;
        *box = sphere_box(set_.spheres.back(), xf);
      } else if (const auto* cn = std::get_if<Cone>(&o.shape)) {
        set_.cones.push_back(ConePrim{*cn, frame_of(xf), cone_axis(*cn)});
        node.kind = PrimKind::kCone;
        node.index = static_cast<int>(set_.cones.size()) - 1;
        *box = cone_box(set_.cones.back(), xf);
      } else if (const auto* ph = std::get_if<Polyhedron>(&o.shape)) {
        node.kind = PrimKind::kConvex;
        node.index = add_convex(*ph, xf, box);
      }
      // Other shapes are rejected as CSG operands by validate_scene().
    }
    csg.nodes[id] = node;
    return id;
  }

  void add_triangles(int obj, const std::vector<Vec3>& pos, const std::vector<Vec3>& nrm,
                     const std::vector<std::array<int, 3>>& tris, const Mat4& xf) {
    const bool identity = xf == Mat4(1.0);
    const glm::dmat3 nxf = glm::transpose(glm::inverse(glm::dmat3(xf)));
    std::vector<Vec3> w(pos.size()), wn(nrm.size());
    for (size_t i = 0; i < pos.size(); ++i) w[i] = identity ? pos[i] : transform_point(xf, pos[i]);
    for (size_t i = 0; i < nrm.size(); ++i) {
      const Vec3 n = identity ? nrm[i] : nxf * nrm[i];
      const double len = glm::length(n);
      wn[i] = len > 0 ? n / len : n;
    }
    for (const auto& t : tris) {
      TrianglePrim tr;
      tr.p0 = w[t[0]];
      tr.e1 = w[t[1]] - w[t[0]];
      tr.e2 = w[t[2]] - w[t[0]];
      const Vec3 n = glm::cross(tr.e1, tr.e2);
      const double len = glm::length(n);
      if (!(len > 0)) continue;  // degenerate triangle: nothing to hit
      tr.normal = n / len;
      if (!wn.empty()) {
        tr.has_normals = true;
        tr.n0 = wn[t[0]];
        tr.n1 = wn[t[1]];
        tr.n2 = wn[t[2]];
      }
      Aabb b;
      b.extend(w[t[0]]);
      b.extend(w[t[1]]);
      b.extend(w[t[2]]);
      set_.triangles.push_back(tr);
      push(PrimKind::kTriangle, static_cast<int>(set_.triangles.size()) - 1, obj, b);
    }
  }

  void add_object(int obj, const Mat4& xf) {
    const Object& o = scene_.objects[obj];
    std::visit(
        [&](const auto& shape) {
          using T = std::decay_t<decltype(shape)>;
          if constexpr (std::is_same_v<T, Sphere>) {
            set_.spheres.push_back(SpherePrim{shape, frame_of(xf)});
            push(PrimKind::kSphere, static_cast<int>(set_.spheres.size()) - 1, obj,
                 sphere_box(set_.spheres.back(), xf));
          } else if constexpr (std::is_same_v<T, Cone>) {
            set_.cones.push_back(ConePrim{shape, frame_of(xf), cone_axis(shape)});
            push(PrimKind::kCone, static_cast<int>(set_.cones.size()) - 1, obj,
                 cone_box(set_.cones.back(), xf));
          } else if constexpr (std::is_same_v<T, Polyhedron>) {
            Aabb b;
            const int idx = add_convex(shape, xf, &b);
            push(PrimKind::kConvex, idx, obj, b);
          } else if constexpr (std::is_same_v<T, Polygon>) {
            PolygonPrim p;
            std::vector<Vec3> w;
            Aabb b;
            for (const Vec3& v : shape.vertices) w.push_back(transform_point(xf, v)), b.extend(w.back());
            p.normal = newell_normal(w);
            p.offset = glm::dot(p.normal, w[0]);
            const Vec3 an = glm::abs(p.normal);
            const int drop = an.x > an.y ? (an.x > an.z ? 0 : 2) : (an.y > an.z ? 1 : 2);
            p.axis_u = (drop + 1) % 3;
            p.axis_v = (drop + 2) % 3;
            for (const Vec3& v : w) p.pts.emplace_back(v[p.axis_u], v[p.axis_v]);
            p.verts = std::move(w);
            // A bent polygon is hit on its plane, where it can reach
            // beyond its vertices' box.
            for (const Vec3& v : polygon_outline(p)) b.extend(v);
            set_.polygons.push_back(std::move(p));
            push(PrimKind::kPolygon, static_cast<int>(set_.polygons.size()) - 1, obj, b);
          } else if constexpr (std::is_same_v<T, Mesh>) {
            add_triangles(obj, shape.positions, shape.normals, shape.triangles, xf);
          } else if constexpr (std::is_same_v<T, Patch>) {
            // SHADING.md: a fan triangulation from vertex 0.
            std::vector<std::array<int, 3>> fan;
            for (int i = 1; i + 1 < static_cast<int>(shape.vertices.size()); ++i) fan.push_back({0, i, i + 1});
            add_triangles(obj, shape.vertices, shape.normals, fan, xf);
          } else if constexpr (std::is_same_v<T, Csg>) {
            CsgPrim csg;
            Aabb b;
            add_csg_node(csg, obj, Mat4(1.0), &b);  // applies the node's own transform
            set_.csgs.push_back(std::move(csg));
            push(PrimKind::kCsg, static_cast<int>(set_.csgs.size()) - 1, obj, b);
          }
        },
        o.shape);
  }

  const Scene& scene_;
  PrimitiveSet set_;
};

}  // namespace

int intersect_sphere(const Sphere& s, const Ray& ray, double tmin, double tmax, Crossing* out) {
  const Vec3 oc = ray.origin - s.center;
  double t0, t1;
  if (!solve_quadratic(glm::dot(ray.dir, ray.dir), 2.0 * glm::dot(oc, ray.dir),
                       glm::dot(oc, oc) - s.radius * s.radius, &t0, &t1)) {
    return 0;
  }
  int n = 0;
  for (double t : {t0, t1}) {
    if (t > tmin && t < tmax) {
      out[n++] = Crossing{t, (ray.origin + t * ray.dir - s.center) / s.radius};
    }
  }
  return n;
}

// Cylinder/cone/frustum side: |q|^2 = (r0 + k s)^2 with s the axial
// coordinate and q the radial vector; caps are disks.
ConeAxis cone_axis(const Cone& c) {
  const Vec3 axis_full = c.apex - c.base;
  ConeAxis ax;
  ax.h = glm::length(axis_full);
  ax.a = axis_full / ax.h;
  ax.k = (c.apex_radius - c.base_radius) / ax.h;
  return ax;
}

int intersect_cone(const Cone& c, const Ray& ray, double tmin, double tmax, Crossing* out) {
  return intersect_cone(c, cone_axis(c), ray, tmin, tmax, out);
}

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

PrimitiveSet build_primitives(const Scene& scene) { return Builder(scene).build(); }

std::vector<Vec3> polygon_outline(const PolygonPrim& p) {
  std::vector<Vec3> out = p.verts;
  const int drop = 3 - p.axis_u - p.axis_v;
  for (Vec3& v : out) {
    const double off = glm::dot(p.normal, v) - p.offset;
    if (std::abs(off) <= 1e-12 * std::max(1.0, max_component(glm::abs(v)))) continue;
    v[drop] = (p.offset - p.normal[p.axis_u] * v[p.axis_u] - p.normal[p.axis_v] * v[p.axis_v]) /
              p.normal[drop];
  }
  return out;
}

Vec3 newell_normal(const std::vector<Vec3>& pts) {
  Vec3 n(0.0);
  for (size_t i = 0; i < pts.size(); ++i) {
    const Vec3& a = pts[i];
    const Vec3& b = pts[(i + 1) % pts.size()];
    n.x += (a.y - b.y) * (a.z + b.z);
    n.y += (a.z - b.z) * (a.x + b.x);
    n.z += (a.x - b.x) * (a.y + b.y);
  }
  const double len = glm::length(n);
  return len > 0 ? n / len : Vec3(0, 0, 1);
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
      const Ray r = to_object(s.frame, ray);
      const Vec3 oc = r.origin - s.s.center;
      double t0, t1;
      if (!solve_quadratic(glm::dot(r.dir, r.dir), 2.0 * glm::dot(oc, r.dir),
                           glm::dot(oc, oc) - s.s.radius * s.s.radius, &t0, &t1)) {
        return false;
      }
      return (t0 > tmin && t0 < tmax) || (t1 > tmin && t1 < tmax);
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[ref.index];
      return intersect_cone(s.c, s.axis, to_object(s.frame, ray), tmin, tmax, nullptr) > 0;
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
      n = finish_quadric(s.frame, intersect_sphere(s.s, to_object(s.frame, ray), tmin, tmax, c),
                         c);
      break;
    }
    case PrimKind::kCone: {
      const ConePrim& s = set.cones[ref.index];
      n = finish_quadric(s.frame, intersect_cone(s.c, s.axis, to_object(s.frame, ray), tmin, tmax, c), c);
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
  if (ref.kind == PrimKind::kTriangle) {
    const TrianglePrim& tr = set.triangles[ref.index];
    if (tr.has_normals) {
      const Vec3 n = (1.0 - c.u - c.v) * tr.n0 + c.u * tr.n1 + c.v * tr.n2;
      const double len = glm::length(n);
      if (len > 0) return n / len;
    }
  }
  return c.normal;
}

}  // namespace locus
