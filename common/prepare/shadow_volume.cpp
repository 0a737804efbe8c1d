// Building the occluders' shadow volumes (paper §4.1, Fig. 6;
// docs/shadow-volumes.md): polygons cut into convex pieces, polyhedra, the
// bounding polyhedra of curved bodies; and build_shadow_volumes, which adds
// the boxes' volumes and the candidate lists of shadow_candidates.cpp. Their
// search at single points is in common/trace/shadow_search.cpp, on scanline
// spans in common/scan/span_shadows.cpp.
#include "common/prepare/shadow_volume.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <optional>

#include "common/base/parallel.h"
#include "common/prepare/bounding.h"
#include "common/prepare/prepared.h"
#include "common/prepare/shadow_candidates.h"
#include "common/scene/polyhedron.h"

namespace locus {
namespace {

bool lex_less(const Vec3& a, const Vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// The plane through the light and the edge {a, b}, with `inner` on its
// inner side. It is computed from the edge's ends in a fixed order, so two
// pieces of a polygon sharing an edge get planes that are exact negations
// of each other: a point is never outside both. False when degenerate (the
// light on the edge's line, or `inner` on the plane).
bool side_plane(const Vec3& light, Vec3 a, Vec3 b, const Vec3& inner, HalfSpace* out) {
  if (lex_less(b, a)) std::swap(a, b);
  Vec3 m = glm::cross(b - a, light - a);
  const double len = glm::length(m);
  if (!(len > 0)) return false;
  m /= len;
  double h = glm::dot(m, a);
  const double side = glm::dot(m, inner) - h;
  if (!(side != 0)) return false;
  if (side > 0) m = -m, h = -h;
  *out = HalfSpace{m, h};
  return true;
}

Vec3 centroid(const std::vector<Vec3>& pts) {
  Vec3 c(0.0);
  for (const Vec3& p : pts) c += p;
  return c / static_cast<double>(std::max<size_t>(1, pts.size()));
}

// A planar outline in 2D: its points on the two axes that drop the
// normal's dominant one (orientation kept or mirrored, never degenerate).
std::vector<Vec2> outline_2d(const std::vector<Vec3>& verts, const Vec3& n) {
  const Vec3 an = glm::abs(n);
  const int drop = an.x > an.y ? (an.x > an.z ? 0 : 2) : (an.y > an.z ? 1 : 2);
  const int u = (drop + 1) % 3, w = (drop + 2) % 3;
  std::vector<Vec2> pts;
  for (const Vec3& p : verts) pts.emplace_back(p[u], p[w]);
  return pts;
}

// Twice the signed area of a 2D outline (> 0 counter-clockwise).
double twice_area(const std::vector<Vec2>& pts) {
  double area = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Vec2& a = pts[i];
    const Vec2& b = pts[(i + 1) % pts.size()];
    area += a.x * b.y - a.y * b.x;
  }
  return area;
}

// A polyhedron as outlines with outward planes: its faces' outlines in one
// array (face k: points[first[k], first[k + 1])), four allocations for a
// sphere's 20 faces rather than 22.
struct Outlines {
  std::vector<Vec3> points;
  std::vector<int> first;
  std::vector<HalfSpace> planes;
  // Its vertices, each once: the faces list every vertex three or more
  // times (an icosahedron's 12 as 60), and a test against every point of
  // the polyhedron needs each once.
  std::vector<Vec3> corners;
};

Outlines outlines_of(const Polyhedron& p) {
  Outlines o;
  const Vec3 c = centroid(p.vertices);
  std::vector<char> used(p.vertices.size(), 0);
  size_t listed = 0;
  for (const auto& face : p.faces) {
    for (int v : face) used[v] = 1;
    listed += face.size();
  }
  for (size_t v = 0; v < p.vertices.size(); ++v) {
    if (used[v]) o.corners.push_back(p.vertices[v]);
  }
  o.points.reserve(listed);
  o.first.reserve(p.faces.size() + 1);
  o.planes.reserve(p.faces.size());
  o.first.push_back(0);
  std::vector<Vec3> pts;
  for (const auto& face : p.faces) {
    pts.clear();
    for (int v : face) pts.push_back(p.vertices[v]);
    Vec3 n = newell_normal(pts);
    const Vec3 fc = centroid(pts);
    if (glm::dot(n, fc - c) < 0) n = -n;
    o.planes.push_back(HalfSpace{n, glm::dot(n, fc)});
    o.points.insert(o.points.end(), pts.begin(), pts.end());
    o.first.push_back(static_cast<int>(o.points.size()));
  }
  return o;
}

// add_polyhedron_volume on faces given by `faces.size()`, `faces.size(k)`
// and `faces.point(k, i)` (a list of outlines, or one flat array), and the
// polyhedron's vertices `corners`, each once.
template <class Faces>
int polyhedron_volume(VolumeSet& out, const Faces& faces, const std::vector<HalfSpace>& face_planes,
                      const Vec3& light, bool solid, const std::vector<Vec3>& verts) {
  // The faces' points in their order, summed as centroid() sums them (the
  // inner point is the one of the faces' points listed with repeats).
  const size_t nf = faces.size();
  Vec3 sum(0.0);
  size_t listed = 0;
  for (size_t k = 0; k < nf; ++k) {
    const size_t m = faces.size(k);
    for (size_t i = 0; i < m; ++i) sum += faces.point(k, i);
    listed += m;
  }
  constexpr size_t kFew = 32;
  char few[kFew];
  std::vector<char> many(nf > kFew ? nf : 0);
  char* front = nf > kFew ? many.data() : few;
  bool any_front = false;
  for (size_t k = 0; k < nf; ++k) {
    front[k] = glm::dot(face_planes[k].m, light) - face_planes[k].h > 0;
    any_front = any_front || front[k];
  }
  ShadowVolume v{VolumeKind::kConvex, static_cast<int>(out.planes.size()), 0};
  if (!any_front) {
    // The light inside (or on) the polyhedron. A ray from a point outside
    // a solid occluder to the light crosses its surface, one from inside
    // does not: the volume is the outside. A bounding polyhedron (the body
    // may be anywhere inside it) gives no volume.
    if (!solid) {
      out.volumes.push_back(ShadowVolume{VolumeKind::kEverywhere, 0, 0});
      return static_cast<int>(out.volumes.size()) - 1;
    }
    v.kind = VolumeKind::kOutside;
    out.planes.insert(out.planes.end(), face_planes.begin(), face_planes.end());
  } else {
    // Cap: the faces turned to the light; the volume lies behind all of
    // them. Sides: the planes through the light and the silhouette edges,
    // the edges of light-facing faces whose plane through the light leaves
    // the whole polyhedron on one side (paper Fig. 6).
    // Sides first: a point beside the volume (most points tested) is
    // rejected by one of them, and the cap rejects only points between the
    // light and the body.
    const Vec3 inner = sum / static_cast<double>(std::max<size_t>(1, listed));
    double scale = glm::length(light - inner);
    for (const Vec3& p : verts) scale = std::max(scale, glm::length(p - inner));
    const double tol = 1e-12 * scale;
    for (size_t k = 0; k < nf; ++k) {
      if (!front[k]) continue;
      const size_t m = faces.size(k);
      for (size_t i = 0; i < m; ++i) {
        HalfSpace s;
        if (!side_plane(light, faces.point(k, i), faces.point(k, (i + 1) % m), inner, &s)) continue;
        bool silhouette = true;
        for (const Vec3& p : verts) {
          if (glm::dot(s.m, p) - s.h > tol) {
            silhouette = false;
            break;
          }
        }
        if (silhouette) out.planes.push_back(s);
      }
    }
    for (size_t k = 0; k < nf; ++k) {
      if (front[k]) out.planes.push_back(face_planes[k]);
    }
  }
  v.count = static_cast<int>(out.planes.size()) - v.first;
  out.volumes.push_back(v);
  return static_cast<int>(out.volumes.size()) - 1;
}

// Faces as a list of outlines.
struct FaceLists {
  const std::vector<std::vector<Vec3>>& f;
  size_t size() const { return f.size(); }
  size_t size(size_t k) const { return f[k].size(); }
  const Vec3& point(size_t k, size_t i) const { return f[k][i]; }
};

// Faces as one array: face k is points[first[k], first[k + 1]).
struct FlatFaces {
  const std::vector<Vec3>& points;
  const std::vector<int>& first;
  size_t size() const { return first.size() - 1; }
  size_t size(size_t k) const { return first[k + 1] - first[k]; }
  const Vec3& point(size_t k, size_t i) const { return points[first[k] + i]; }
};

// Do two edges that share no vertex meet (touch or cross)?
bool edges_meet(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  auto orient = [](const Vec2& p, const Vec2& q, const Vec2& r) {
    const double v = (q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x);
    return (v > 0) - (v < 0);
  };
  auto on = [](const Vec2& p, const Vec2& q, const Vec2& r) {  // r on segment pq, collinear
    return std::min(p.x, q.x) <= r.x && r.x <= std::max(p.x, q.x) && std::min(p.y, q.y) <= r.y &&
           r.y <= std::max(p.y, q.y);
  };
  const int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
  if (o1 != o2 && o3 != o4) return true;
  return (o1 == 0 && on(a, b, c)) || (o2 == 0 && on(a, b, d)) || (o3 == 0 && on(c, d, a)) ||
         (o4 == 0 && on(c, d, b));
}

// Ear clipping of a simple polygon given in 2D (any orientation). Appends
// index triples to `tris`; false if the outline is not simple.
bool ear_clip(const std::vector<Vec2>& pts, std::vector<std::array<int, 3>>& tris) {
  const size_t m = pts.size();
  for (size_t i = 0; i < m; ++i) {
    for (size_t j = i + 2; j < m; ++j) {
      if (i == 0 && j == m - 1) continue;  // neighbours through the closing edge
      if (edges_meet(pts[i], pts[i + 1], pts[j], pts[(j + 1) % m])) return false;
    }
  }
  std::vector<int> idx(pts.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  const double area = twice_area(pts);
  if (area == 0) return false;
  const double orient = area > 0 ? 1.0 : -1.0;
  auto cross = [&](int i, int j, int k) {
    const Vec2 u = pts[j] - pts[i], v = pts[k] - pts[j];
    return orient * (u.x * v.y - u.y * v.x);
  };
  // p inside or on the triangle (a, b, c) wound positively.
  auto in_triangle = [&](const Vec2& p, int a, int b, int c) {
    auto side = [&](int i, int j) {
      const Vec2 u = pts[j] - pts[i], v = p - pts[i];
      return orient * (u.x * v.y - u.y * v.x);
    };
    return side(a, b) >= 0 && side(b, c) >= 0 && side(c, a) >= 0;
  };
  while (idx.size() > 3) {
    const int n = static_cast<int>(idx.size());
    bool cut = false;
    for (int k = 0; k < n && !cut; ++k) {
      const int a = idx[(k + n - 1) % n], b = idx[k], c = idx[(k + 1) % n];
      const double turn = cross(a, b, c);
      if (turn == 0) {
        // b on the line through its neighbours: between them it is a
        // redundant vertex; a spike means the outline is not simple.
        if (glm::dot(pts[a] - pts[b], pts[c] - pts[b]) >= 0) return false;
        idx.erase(idx.begin() + k);
        cut = true;
        break;
      }
      if (turn < 0) continue;  // reflex corner
      bool ear = true;
      for (int j = 0; j < n && ear; ++j) {
        const int v = idx[j];
        if (v == a || v == b || v == c) continue;
        if (in_triangle(pts[v], a, b, c)) ear = false;
      }
      if (!ear) continue;
      tris.push_back({a, b, c});
      idx.erase(idx.begin() + k);
      cut = true;
    }
    if (!cut) return false;
  }
  if (idx.size() == 3 && cross(idx[0], idx[1], idx[2]) > 0)
    tris.push_back({idx[0], idx[1], idx[2]});
  return true;
}

// Is the outline (2D) convex and simple? Collinear and repeated vertices
// are allowed.
bool is_convex(const std::vector<Vec2>& pts) {
  std::vector<Vec2> edges;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Vec2 e = pts[(i + 1) % pts.size()] - pts[i];
    if (e != Vec2(0.0)) edges.push_back(e);
  }
  int sign = 0;
  double turning = 0;
  for (size_t i = 0; i < edges.size(); ++i) {
    const Vec2& a = edges[i];
    const Vec2& b = edges[(i + 1) % edges.size()];
    const double c = a.x * b.y - a.y * b.x;
    const int s = (c > 0) - (c < 0);
    if (s != 0) {
      if (sign != 0 && s != sign) return false;
      sign = s;
    }
    turning += std::atan2(c, glm::dot(a, b));
  }
  // A star polygon turns the same way at every corner but winds twice.
  return sign != 0 && std::abs(turning) < 2.0 * std::numbers::pi + 1e-6;
}

// Appends the volume of a convex planar piece: the cap (the plane, on the
// far side from the light) and the planes through the light and each edge.
void add_piece(VolumeSet& out, const std::vector<Vec3>& pts, const HalfSpace& cap,
               const Vec3& light) {
  ShadowVolume v{VolumeKind::kConvex, static_cast<int>(out.planes.size()), 0};
  out.planes.push_back(cap);
  const Vec3 inner = centroid(pts);
  for (size_t i = 0; i < pts.size(); ++i) {
    HalfSpace s;
    if (side_plane(light, pts[i], pts[(i + 1) % pts.size()], inner, &s)) out.planes.push_back(s);
  }
  v.count = static_cast<int>(out.planes.size()) - v.first;
  out.volumes.push_back(v);
}

// The outline of a flat primitive (polygon, triangle) as the ray tracer
// hits it.
std::vector<Vec3> flat_outline(const PreparedScene& ps, int prim) {
  const PrimRef& ref = ps.prims.prims[prim];
  if (ref.kind == PrimKind::kPolygon) return polygon_outline(ps.prims.polygons[ref.index]);
  const TrianglePrim& t = ps.prims.triangles[ref.index];
  return {t.p0, t.p0 + t.e1, t.p0 + t.e2};
}

// The plane of a flat primitive (polygon, triangle); false for others.
bool flat_plane(const PreparedScene& ps, int prim, HalfSpace* out) {
  const PrimRef& ref = ps.prims.prims[prim];
  if (ref.kind == PrimKind::kPolygon) {
    const PolygonPrim& p = ps.prims.polygons[ref.index];
    *out = HalfSpace{p.normal, p.offset};
    return true;
  }
  if (ref.kind == PrimKind::kTriangle) {
    const TrianglePrim& t = ps.prims.triangles[ref.index];
    *out = HalfSpace{t.normal, glm::dot(t.normal, t.p0)};
    return true;
  }
  return false;
}

// The points that bound a primitive: every point of it lies in their hull.
// Curved bodies and CSG: the vertices of their bounding polyhedra.
std::vector<Vec3> hull_points(const PreparedScene& ps, int prim,
                              const std::vector<Outlines>& leaves) {
  const PrimRef& ref = ps.prims.prims[prim];
  std::vector<Vec3> pts;
  switch (ref.kind) {
    case PrimKind::kPolygon:
    case PrimKind::kTriangle:
      pts = flat_outline(ps, prim);
      break;
    case PrimKind::kConvex:
      for (const auto& f : ps.prims.convexes[ref.index].faces)
        pts.insert(pts.end(), f.begin(), f.end());
      // Each vertex once (the tests using these points ask whether some
      // or every point passes, so repeats only cost time).
      std::sort(pts.begin(), pts.end(), lex_less);
      pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
      break;
    default:
      for (const Outlines& o : leaves) pts.insert(pts.end(), o.corners.begin(), o.corners.end());
      break;
  }
  return pts;
}

// The volume of the convex hull of a planar outline (plane `plane`).
int add_hull_volume(VolumeSet& out, const std::vector<Vec3>& verts, const HalfSpace& plane,
                    const Vec3& light) {
  const std::vector<int> hull = convex_hull_2d(outline_2d(verts, plane.m));
  const double s = glm::dot(plane.m, light) - plane.h;
  if (hull.size() < 3 || s == 0) {
    out.volumes.push_back(ShadowVolume{VolumeKind::kEverywhere, 0, 0});
    return static_cast<int>(out.volumes.size()) - 1;
  }
  std::vector<Vec3> pts;
  for (int i : hull) pts.push_back(verts[i]);
  add_piece(out, pts, s > 0 ? plane : HalfSpace{-plane.m, -plane.h}, light);
  return static_cast<int>(out.volumes.size()) - 1;
}

void add_occluder(const PreparedScene& ps, int prim, const std::vector<Outlines>& leaves,
                  const std::optional<ConvexPieces>& pieces, LightVolumes& lv) {
  const PrimRef& ref = ps.prims.prims[prim];
  const Vec3& light = lv.position;
  LightVolumes::Occluder oc;
  oc.first = static_cast<int>(lv.set.volumes.size());
  switch (ref.kind) {
    case PrimKind::kPolygon:
    case PrimKind::kTriangle: {
      HalfSpace plane;
      flat_plane(ps, prim, &plane);
      const std::vector<Vec3> verts = flat_outline(ps, prim);
      oc.decides = is_opaque(ps, prim);
      if (glm::dot(plane.m, light) == plane.h) break;  // edge-on to the light: no shadow
      if (!pieces) {
        // Not simple, so not cut: the hull's volume, then the exact test.
        oc.decides = false;
        add_hull_volume(lv.set, verts, plane, light);
        break;
      }
      if (!oc.decides && pieces->size() > 1) {
        // Transparent: the exact crossings decide anyway (eqs. (2), (3)),
        // the hull's volume is enough to find the candidates.
        add_hull_volume(lv.set, verts, plane, light);
        break;
      }
      add_pieces_volumes(lv.set, verts, *pieces, plane.m, plane.h, light);
      if (pieces->size() > 1) {
        // A concave polygon's pieces: the volume of its convex hull bounds
        // them all, and is tested first.
        oc.count = static_cast<int>(lv.set.volumes.size()) - oc.first;
        oc.bound = add_hull_volume(lv.set, verts, plane, light);
        lv.occluders.push_back(oc);
        return;
      }
      break;
    }
    case PrimKind::kConvex: {
      const ConvexPrim& c = ps.prims.convexes[ref.index];
      std::vector<HalfSpace> planes;
      for (size_t k = 0; k < c.normals.size(); ++k)
        planes.push_back(HalfSpace{c.normals[k], c.offsets[k]});
      oc.decides = is_opaque(ps, prim);
      add_polyhedron_volume(lv.set, c.faces, planes, light, oc.decides, nullptr);
      break;
    }
    default: {
      // Curved bodies and CSG: their bounding polyhedra's volumes, then an
      // exact test (paper §4.1).
      oc.decides = false;
      for (const Outlines& o : leaves)
        polyhedron_volume(lv.set, FlatFaces{o.points, o.first}, o.planes, light, false, o.corners);
      break;
    }
  }
  oc.count = static_cast<int>(lv.set.volumes.size()) - oc.first;
  lv.occluders.push_back(oc);
}

}  // namespace

bool VolumeSet::contains(int v, const Vec3& p, double slack) const {
  const ShadowVolume& vol = volumes[v];
  switch (vol.kind) {
    case VolumeKind::kEverywhere:
      return true;
    case VolumeKind::kConvex:
      return inside_planes(vol.first, vol.count, p, slack);
    case VolumeKind::kOutside:
      for (int i = vol.first; i < vol.first + vol.count; ++i) {
        if (glm::dot(planes[i].m, p) - planes[i].h > -slack) return true;
      }
      return false;
  }
  return true;
}

int add_polyhedron_volume(VolumeSet& out, const std::vector<std::vector<Vec3>>& faces,
                          const std::vector<HalfSpace>& face_planes, const Vec3& light, bool solid,
                          const std::vector<Vec3>* corners) {
  if (corners) return polyhedron_volume(out, FaceLists{faces}, face_planes, light, solid, *corners);
  std::vector<Vec3> all;
  for (const auto& f : faces) all.insert(all.end(), f.begin(), f.end());
  return polyhedron_volume(out, FaceLists{faces}, face_planes, light, solid, all);
}

std::optional<ConvexPieces> convex_pieces(const std::vector<Vec3>& verts, const Vec3& n) {
  ConvexPieces out;
  if (verts.size() < 3) return out;
  const std::vector<Vec2> pts = outline_2d(verts, n);
  if (is_convex(pts)) {
    out.emplace_back(verts.size());
    for (size_t i = 0; i < verts.size(); ++i) out[0][i] = static_cast<int>(i);
    return out;
  }
  // A concave outline (SPD gears): triangles, then merged across their
  // diagonals while the union stays convex (Hertel-Mehlhorn), which leaves
  // a few times fewer pieces.
  std::vector<std::array<int, 3>> tris;
  if (!ear_clip(pts, tris)) return std::nullopt;
  // One pass over the diagonals (Hertel-Mehlhorn): drop each one whose two
  // pieces make a convex union. Pieces keep the outline's orientation.
  std::vector<std::vector<int>> piece;
  for (const auto& t : tris) piece.push_back({t[0], t[1], t[2]});
  std::vector<int> alive(piece.size(), 1);
  std::map<std::pair<int, int>, int> owner;  // directed edge -> piece
  for (size_t p = 0; p < piece.size(); ++p) {
    for (size_t i = 0; i < 3; ++i)
      owner[{piece[p][i], piece[p][(i + 1) % 3]}] = static_cast<int>(p);
  }
  const double orient = twice_area(pts) > 0 ? 1.0 : -1.0;
  auto convex_corner = [&](int i, int j, int k) {
    const Vec2 e = pts[j] - pts[i], f = pts[k] - pts[j];
    return orient * (e.x * f.y - e.y * f.x) >= 0;
  };
  auto rotated = [](const std::vector<int>& v, int start) {
    std::vector<int> r(v);
    std::rotate(r.begin(), std::find(r.begin(), r.end(), start), r.end());
    return r;
  };
  for (const auto& t : tris) {
    for (int e = 0; e < 3; ++e) {
      const int a = t[e], b = t[(e + 1) % 3];
      const auto pa = owner.find({a, b}), pb = owner.find({b, a});
      if (pa == owner.end() || pb == owner.end() || pa->second == pb->second) continue;
      const int p = pa->second, q = pb->second;
      std::vector<int> m = rotated(piece[p], b);        // b ... a
      const std::vector<int> r = rotated(piece[q], a);  // a ... b
      // The union is convex when its corners at a and b are.
      if (!convex_corner(m[m.size() - 2], a, r[1]) || !convex_corner(r[r.size() - 2], b, m[1])) {
        continue;
      }
      m.insert(m.end(), r.begin() + 1, r.end() - 1);
      owner.erase({a, b});
      owner.erase({b, a});
      for (size_t i = 0; i < m.size(); ++i) owner[{m[i], m[(i + 1) % m.size()]}] = p;
      piece[p] = std::move(m);
      alive[q] = 0;
    }
  }
  for (size_t p = 0; p < piece.size(); ++p) {
    if (alive[p]) out.push_back(std::move(piece[p]));
  }
  return out;
}

int add_polygon_volumes(VolumeSet& out, const std::vector<Vec3>& verts, const Vec3& n, double d,
                        const Vec3& light) {
  const auto pieces = convex_pieces(verts, n);
  if (!pieces) return -1;
  return add_pieces_volumes(out, verts, *pieces, n, d, light);
}

int add_pieces_volumes(VolumeSet& out, const std::vector<Vec3>& verts, const ConvexPieces& pieces,
                       const Vec3& n, double d, const Vec3& light) {
  const double s = glm::dot(n, light) - d;
  if (s == 0) return 0;  // edge-on to the light: no shadow
  // The cap keeps the side of the plane away from the light.
  const HalfSpace cap = s > 0 ? HalfSpace{n, d} : HalfSpace{-n, -d};
  std::vector<Vec3> pts;
  for (const auto& piece : pieces) {
    pts.clear();
    for (int i : piece) pts.push_back(verts[i]);
    add_piece(out, pts, cap, light);
  }
  return static_cast<int>(pieces.size());
}

namespace {

// What the occluders' volumes are made of, the same for every light: the
// bounding polyhedra of curved bodies (one per CSG leaf) and the convex
// pieces of polygons (triangles are one), per primitive.
struct OccluderShapes {
  std::vector<std::vector<Outlines>> leaves;
  std::vector<std::optional<ConvexPieces>> pieces;
};

// Primitives [begin, end) of s, sized for every primitive beforehand: each
// primitive's shapes depend on it alone, so chunks may run on any threads.
void occluder_shapes(const PreparedScene& ps, int begin, int end, OccluderShapes& s) {
  const PrimitiveSet& set = ps.prims;
  for (int i = begin; i < end; ++i) {
    const PrimRef& ref = set.prims[i];
    if (ref.kind == PrimKind::kSphere || ref.kind == PrimKind::kCone ||
        ref.kind == PrimKind::kCsg) {
      for (const Polyhedron& p : bounding_polyhedra(ps.scene, ref.object)) {
        s.leaves[i].push_back(outlines_of(p));
      }
    } else if (ref.kind == PrimKind::kPolygon) {
      s.pieces[i] = convex_pieces(flat_outline(ps, i), set.polygons[ref.index].normal);
    } else if (ref.kind == PrimKind::kTriangle) {
      s.pieces[i] = ConvexPieces{{0, 1, 2}};
    }
  }
}

// Per primitive in [begin, end), what the front/back relations use of it
// (ReceiverHull); `hulls` holds every primitive's slot.
void receiver_hulls(const PreparedScene& ps, const OccluderShapes& shapes, int begin, int end,
                    std::vector<ReceiverHull>& hulls) {
  for (int i = begin; i < end; ++i) {
    hulls[i].points = hull_points(ps, i, shapes.leaves[i]);
    hulls[i].flat = flat_plane(ps, i, &hulls[i].plane);
  }
}

// The planes' products with the camera frame (VolumeSet::cam), for the
// scanline intervals.
void add_camera_dots(const CameraFrame& cam, VolumeSet& set) {
  set.cam.resize(set.planes.size());
  for (size_t i = 0; i < set.planes.size(); ++i) {
    const HalfSpace& p = set.planes[i];
    set.cam[i] = {glm::dot(p.m, cam.u), glm::dot(p.m, cam.v), glm::dot(p.m, cam.w),
                  glm::dot(p.m, cam.from) - p.h};
  }
}

}  // namespace

namespace {

// A light's volumes built in pieces (build_shadow_volumes): `part`, made by
// itself from an empty LightVolumes, appended to `lv`, which then holds
// what one pass over both ranges would have made. Planes, volumes and
// occluders go to the end; the indices `part` holds into its own arrays
// move by the sizes `lv`'s already had (a kEverywhere volume refers to no
// plane and keeps its {0, 0}).
void append_part(LightVolumes& lv, LightVolumes&& part) {
  if (lv.set.volumes.empty() && lv.set.planes.empty() && lv.occluders.empty() &&
      lv.node_volume.empty()) {
    lv.set = std::move(part.set);
    lv.occluders = std::move(part.occluders);
    lv.node_volume = std::move(part.node_volume);
    return;
  }
  const int planes = static_cast<int>(lv.set.planes.size());
  const int volumes = static_cast<int>(lv.set.volumes.size());
  lv.set.planes.insert(lv.set.planes.end(), part.set.planes.begin(), part.set.planes.end());
  for (ShadowVolume v : part.set.volumes) {
    if (v.kind != VolumeKind::kEverywhere) v.first += planes;
    lv.set.volumes.push_back(v);
  }
  for (LightVolumes::Occluder oc : part.occluders) {
    oc.first += volumes;
    if (oc.bound >= 0) oc.bound += volumes;
    lv.occluders.push_back(oc);
  }
  for (const int v : part.node_volume) lv.node_volume.push_back(v + volumes);
}

}  // namespace

ShadowVolumes build_shadow_volumes(const PreparedScene& ps, bool search, int threads) {
  // Primitives (or boxes) per chunk: a chunk costs some tens of
  // microseconds or more, far above what handing it to a thread costs.
  constexpr int kGrain = 256;
  threads = std::max(1, threads);
  ShadowVolumes sv;
  sv.search = search;
  const int n = static_cast<int>(ps.prims.prims.size());
  const double scale = ps.world_scale;
  // The stages below depend on the ones above; inside a stage, every
  // chunk's result goes to its own slot, and slots are joined in their
  // order, so the volumes are the same, bit for bit, for any number of
  // threads (tests/prepare/parallel_prepare_test.cpp).
  OccluderShapes shapes;
  shapes.leaves.resize(n);
  shapes.pieces.resize(n);
  parallel_chunks(n, threads, kGrain,
                  [&](int begin, int end) { occluder_shapes(ps, begin, end, shapes); });
  std::shared_ptr<SearchShapes> search_with;
  if (search) {
    std::vector<ReceiverHull> hulls(n);
    parallel_chunks(n, threads, kGrain,
                    [&](int begin, int end) { receiver_hulls(ps, shapes, begin, end, hulls); });
    search_with = std::make_shared<SearchShapes>(search_shapes(ps, std::move(hulls), sv.parts));
    sv.shapes = search_with;
  }
  // Each light's volumes (paper §4.1): its occluders' and, for the search,
  // its boxes', in chunks of primitives and of boxes, every light's chunks
  // side by side; then each light's chunks joined in order.
  const int lights = static_cast<int>(ps.scene.lights.size());
  const int boxes = search ? static_cast<int>(search_with->boxes.size()) : 0;
  // Enough chunks over all lights for about four per thread.
  const int per_light = std::max(1, 4 * threads / std::max(1, lights));
  const int occ_chunks = chunk_count(n, kGrain, per_light);
  const int box_chunks = search ? chunk_count(boxes, kGrain, per_light) : 0;
  const int tasks = occ_chunks + box_chunks;
  std::vector<LightVolumes> parts(static_cast<size_t>(lights) * tasks);
  sv.lights.resize(lights);
  for (int j = 0; j < lights; ++j) {
    LightVolumes& lv = sv.lights[j];
    lv.position = ps.scene.lights[j].position;
    // Shadow-ray origins lie ps.eps off the surface: conservative tests must
    // reach that far, and beyond rounding.
    lv.slack = 4.0 * ps.eps + 1e-12 * (scale + glm::length(lv.position));
  }
  parallel_for(lights * tasks, threads, [&](int t) {
    const int j = t / tasks, c = t % tasks;
    LightVolumes& part = parts[t];
    part.position = sv.lights[j].position;
    if (c < occ_chunks) {
      for (int i = chunk_edge(n, c, occ_chunks); i < chunk_edge(n, c + 1, occ_chunks); ++i) {
        add_occluder(ps, i, shapes.leaves[i], shapes.pieces[i], part);
      }
    } else {
      const int b = c - occ_chunks;
      add_box_volumes(*search_with, chunk_edge(boxes, b, box_chunks),
                      chunk_edge(boxes, b + 1, box_chunks), part);
    }
  });
  parallel_for(lights, threads, [&](int j) {
    LightVolumes& lv = sv.lights[j];
    // Reserved exactly, and each part freed once joined: growth by doubling
    // would hold up to twice the volumes at the peak (a quarter of a big
    // scene's memory, issue #27).
    size_t planes = 0, volumes = 0, occluders = 0, nodes = 0;
    for (int c = 0; c < tasks; ++c) {
      const LightVolumes& part = parts[j * tasks + c];
      planes += part.set.planes.size();
      volumes += part.set.volumes.size();
      occluders += part.occluders.size();
      nodes += part.node_volume.size();
    }
    for (int c = 0; c < tasks; ++c) {
      append_part(lv, std::move(parts[j * tasks + c]));
      parts[j * tasks + c] = LightVolumes{};
      // After the first part that held anything was moved in (a no-op
      // once reserved).
      lv.set.planes.reserve(planes);
      lv.set.volumes.reserve(volumes);
      lv.occluders.reserve(occluders);
      lv.node_volume.reserve(nodes);
    }
    if (search) lv.candidates = CandidateTable(n);
    add_camera_dots(ps.camera, lv.set);
  });
  return sv;
}

bool is_opaque(const PreparedScene& ps, int prim) {
  const Scene& s = ps.scene;
  return s.materials[s.objects[ps.prims.prims[prim].object].material].t <= 0.0;
}

}  // namespace locus
