// Building the primitive set (geometry.h): a scene's objects flattened into
// world-space primitives, their frames and bounding boxes, and CSG trees
// compiled to node arrays. Their ray intersections are in intersect.cpp.
#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>
#include <variant>

#include "common/geometry/geometry.h"

namespace locus {
namespace {

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

// PolygonPrim's edge buckets (geometry.h), about 4 edges to a bucket. An
// edge changes the crossing test's answer at v only when one end lies above
// v and the other not: min <= v < max of its ends' v. bucket_of is monotone,
// so that v's bucket lies between those of the edge's ends, and the edge is
// listed in each of them.
void bucket_edges(PolygonPrim& p) {
  const int n = static_cast<int>(p.pts.size());
  if (n <= kPolygonBucketAbove) return;
  double lo = p.pts[0].y, hi = lo;
  for (const Vec2& q : p.pts) lo = std::min(lo, q.y), hi = std::max(hi, q.y);
  const int buckets = n / 4;
  p.v_lo = lo;
  p.v_scale = buckets / (hi - lo);
  if (!(hi > lo) || !std::isfinite(p.v_scale)) return;
  p.bucket_first.assign(buckets + 1, 0);
  std::vector<std::array<int, 2>> range(n);
  for (int i = 0, j = n - 1; i < n; j = i++) {
    const double a = p.pts[i].y, b = p.pts[j].y;
    range[i] = {p.bucket_of(std::min(a, b)), p.bucket_of(std::max(a, b))};
    for (int k = range[i][0]; k <= range[i][1]; ++k) ++p.bucket_first[k + 1];
  }
  for (int k = 0; k < buckets; ++k) p.bucket_first[k + 1] += p.bucket_first[k];
  std::vector<int> fill(p.bucket_first.begin(), p.bucket_first.end() - 1);
  p.edges.resize(p.bucket_first.back());
  for (int i = 0, j = n - 1; i < n; j = i++) {
    for (int k = range[i][0]; k <= range[i][1]; ++k) {
      p.edges[fill[k]++] = PolygonPrim::Edge{p.pts[i], p.pts[j]};
    }
  }
}

class Builder {
 public:
  explicit Builder(const Scene& scene) : scene_(scene) {}

  PrimitiveSet build() {
    const std::vector<bool> operand = csg_operand_mask(scene_);
    // Room for a primitive an object (a mesh may make more), and for the
    // polygons: no copies as the arrays grow (SPD tetra level 9's 262,144
    // polygons: 100 -> 73 ms with the vectors below reserved).
    set_.prims.reserve(scene_.objects.size());
    set_.bounds.reserve(scene_.objects.size());
    size_t polygons = 0;
    for (const Object& o : scene_.objects) polygons += std::holds_alternative<Polygon>(o.shape);
    set_.polygons.reserve(polygons);
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
            std::vector<Vec3>& w = p.verts;
            w.reserve(shape.vertices.size());
            Aabb b;
            for (const Vec3& v : shape.vertices) {
              w.push_back(transform_point(xf, v));
              b.extend(w.back());
            }
            p.normal = newell_normal(w);
            p.offset = glm::dot(p.normal, w[0]);
            const Vec3 an = glm::abs(p.normal);
            const int drop = an.x > an.y ? (an.x > an.z ? 0 : 2) : (an.y > an.z ? 1 : 2);
            p.axis_u = (drop + 1) % 3;
            p.axis_v = (drop + 2) % 3;
            p.pts.reserve(w.size());
            for (const Vec3& v : w) p.pts.emplace_back(v[p.axis_u], v[p.axis_v]);
            bucket_edges(p);
            // A bent polygon is hit on its plane, where it can reach
            // beyond its vertices' box.
            for (const Vec3& v : w) b.extend(outline_point(p, v));
            set_.polygons.push_back(std::move(p));
            push(PrimKind::kPolygon, static_cast<int>(set_.polygons.size()) - 1, obj, b);
          } else if constexpr (std::is_same_v<T, Mesh>) {
            add_triangles(obj, shape.positions, shape.normals, shape.triangles, xf);
          } else if constexpr (std::is_same_v<T, Patch>) {
            // SHADING.md: a fan triangulation from vertex 0.
            std::vector<std::array<int, 3>> fan;
            for (int i = 1; i + 1 < static_cast<int>(shape.vertices.size()); ++i) {
              fan.push_back({0, i, i + 1});
            }
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

// A cone's axis for intersect_cone: unit direction a, length h, and the
// radius's slope k along it.
ConeAxis cone_axis(const Cone& c) {
  const Vec3 axis_full = c.apex - c.base;
  ConeAxis ax;
  ax.h = glm::length(axis_full);
  ax.a = axis_full / ax.h;
  ax.k = (c.apex_radius - c.base_radius) / ax.h;
  return ax;
}

PrimitiveSet build_primitives(const Scene& scene) { return Builder(scene).build(); }

std::vector<int> convex_hull_2d(const std::vector<Vec2>& p) {
  if (p.size() < 3) return {};
  std::vector<int> idx(p.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  std::sort(idx.begin(), idx.end(),
            [&](int a, int b) { return p[a].x != p[b].x ? p[a].x < p[b].x : p[a].y < p[b].y; });
  auto turn = [&](int o, int a, int b) {
    const Vec2 e = p[a] - p[o], f = p[b] - p[o];
    return e.x * f.y - e.y * f.x;
  };
  std::vector<int> hull(2 * idx.size());
  size_t k = 0;
  for (size_t i = 0; i < idx.size(); ++i) {  // lower chain
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], idx[i]) <= 0) --k;
    hull[k++] = idx[i];
  }
  for (size_t i = idx.size() - 1, t = k + 1; i > 0; --i) {  // upper chain
    while (k >= t && turn(hull[k - 2], hull[k - 1], idx[i - 1]) <= 0) --k;
    hull[k++] = idx[i - 1];
  }
  hull.resize(k > 0 ? k - 1 : 0);  // the first point closes the upper chain
  return hull;
}

Vec3 outline_point(const PolygonPrim& p, Vec3 v) {
  const double off = glm::dot(p.normal, v) - p.offset;
  if (std::abs(off) <= 1e-12 * std::max(1.0, max_component(glm::abs(v)))) return v;
  const int drop = 3 - p.axis_u - p.axis_v;
  v[drop] = (p.offset - p.normal[p.axis_u] * v[p.axis_u] - p.normal[p.axis_v] * v[p.axis_v]) /
            p.normal[drop];
  return v;
}

std::vector<Vec3> polygon_outline(const PolygonPrim& p) {
  std::vector<Vec3> out;
  out.reserve(p.verts.size());
  for (const Vec3& v : p.verts) out.push_back(outline_point(p, v));
  return out;
}

Vec3 newell_normal(const std::vector<Vec3>& pts) {
  const Vec3 n = newell_vector(pts);
  const double len = glm::length(n);
  return len > 0 ? n / len : Vec3(0, 0, 1);
}

}  // namespace locus
