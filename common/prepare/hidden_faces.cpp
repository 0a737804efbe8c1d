#include "common/prepare/hidden_faces.h"

#include <algorithm>
#include <bit>
#include <cmath>

#include "common/prepare/prepared.h"

namespace locus {
namespace {

uint64_t mix64(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdULL;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ULL;
  x ^= x >> 33;
  return x;
}

size_t table_size(size_t n) { return std::bit_ceil(std::max<size_t>(16, 2 * n)); }

// How far ahead of the polygon in hand the tables' slots for a later one
// are fetched: their lookups miss the caches (random slots of tables of
// many MB: SPD tetra level 9's 786,432 corners), and several misses in
// flight cost about what one does.
constexpr int kPrefetchAhead = 8;

// Vertices matched by their exact coordinates (-0 is 0): open addressing.
class VertexIds {
 public:
  explicit VertexIds(size_t n) : slot_(table_size(n), -1) {}
  int id(const Vec3& p) {
    const Vec3 q = p + Vec3(0.0);  // -0.0 + 0.0 is +0.0
    const size_t mask = slot_.size() - 1;
    for (size_t h = hash(q) & mask;; h = (h + 1) & mask) {
      const int s = slot_[h];
      if (s < 0) {
        slot_[h] = static_cast<int>(points.size());
        points.push_back(q);
        return slot_[h];
      }
      if (points[s] == q) return s;
    }
  }
  // A hint: id(p) will be asked soon.
  void prefetch(const Vec3& p) const {
    __builtin_prefetch(&slot_[hash(p + Vec3(0.0)) & (slot_.size() - 1)]);
  }
  std::vector<Vec3> points;

 private:
  static uint64_t hash(const Vec3& q) {
    return mix64(std::bit_cast<uint64_t>(q.x) ^
                 mix64(std::bit_cast<uint64_t>(q.y) ^ mix64(std::bit_cast<uint64_t>(q.z))));
  }
  std::vector<int> slot_;
};

// Undirected edges: the first face walking it, its direction, how many.
class EdgeTable {
 public:
  struct Entry {  // 16 bytes: four to a cache line
    uint64_t key = ~0ULL;
    int face = -1;
    bool forward = false;
    uint8_t count = 0;  // 0-3
  };
  explicit EdgeTable(size_t n) : e_(table_size(n)) {}
  // The entry of edge {a, b}, made if new.
  Entry& at(int a, int b) {
    const uint64_t key = key_of(a, b);
    const size_t mask = e_.size() - 1;
    for (size_t h = mix64(key) & mask;; h = (h + 1) & mask) {
      if (e_[h].key == key) return e_[h];
      if (e_[h].count == 0) {
        e_[h].key = key;
        return e_[h];
      }
    }
  }
  // A hint: at(a, b) will be asked soon.
  void prefetch(int a, int b) const { __builtin_prefetch(&e_[mix64(key_of(a, b)) & (e_.size() - 1)]); }
  const std::vector<Entry>& entries() const { return e_; }

 private:
  static uint64_t key_of(int a, int b) {
    return (static_cast<uint64_t>(std::min(a, b)) << 32) | static_cast<uint32_t>(std::max(a, b));
  }
  std::vector<Entry> e_;
};

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

// Deeper than z_near and than hither: nothing of it is clipped, nor cut
// away by hither's sphere (whose pixels are traced, local_rows).
bool beyond_near(const CameraFrame& cam, double z_near, const Vec3& p) {
  return glm::dot(p - cam.from, cam.w) > std::max(z_near, cam.hither);
}

}  // namespace

ClosedSolids closed_convex_solids(const PrimitiveSet& set) {
  ClosedSolids out;
  std::vector<int> polys;  // prim indices of the polygons
  size_t corners = 0;
  for (size_t i = 0; i < set.prims.size(); ++i) {
    if (set.prims[i].kind != PrimKind::kPolygon) continue;
    polys.push_back(static_cast<int>(i));
    corners += set.polygons[set.prims[i].index].verts.size();
  }
  const int n = static_cast<int>(polys.size());
  if (n < 4) return out;
  auto poly = [&](int j) -> const PolygonPrim& { return set.polygons[set.prims[polys[j]].index]; };

  // Each polygon's corners as vertex ids; its edges paired with the other
  // faces' (a closed, consistently oriented surface walks each edge once
  // each way); the faces joined by edges into surfaces (union-find).
  VertexIds ids(corners);
  std::vector<int> first(n + 1, 0), corner(corners);
  std::vector<uint8_t> bad(n, 0);
  for (int j = 0; j < n; ++j) {
    const PolygonPrim& p = poly(j);
    if (j + kPrefetchAhead < n) {
      for (const Vec3& v : poly(j + kPrefetchAhead).verts) ids.prefetch(v);
    }
    first[j + 1] = first[j] + static_cast<int>(p.verts.size());
    for (size_t k = 0; k < p.verts.size(); ++k) {
      const Vec3& v = p.verts[k];
      corner[first[j] + k] = ids.id(v);
      // A bent polygon is hit on its plane, not at its vertices
      // (polygon_outline).
      if (std::abs(glm::dot(p.normal, v) - p.offset) >
          1e-12 * std::max(1.0, max_component(glm::abs(v))))
        bad[j] = 1;
    }
  }
  std::vector<int> parent(n);
  for (int j = 0; j < n; ++j) parent[j] = j;
  EdgeTable edges(corners);
  for (int j = 0; j < n; ++j) {
    if (j + kPrefetchAhead < n) {
      const int f = first[j + kPrefetchAhead], l = first[j + kPrefetchAhead + 1];
      for (int c = f; c < l; ++c) edges.prefetch(corner[c], corner[c + 1 < l ? c + 1 : f]);
    }
    const int m = first[j + 1] - first[j];
    for (int k = 0; k < m; ++k) {
      const int a = corner[first[j] + k], b = corner[first[j] + (k + 1) % m];
      if (a == b) {
        bad[j] = 1;
        continue;
      }
      EdgeTable::Entry& e = edges.at(a, b);
      if (e.count == 0) {
        e.face = j;
        e.forward = a < b;
        e.count = 1;
      } else if (e.count == 1 && e.forward != (a < b) && e.face != j) {
        e.count = 2;
        parent[find_root(parent, j)] = find_root(parent, e.face);
      } else {
        e.count = 3;  // a third face, or walked the same way twice
        bad[j] = 1;
      }
    }
  }
  for (const EdgeTable::Entry& e : edges.entries()) {
    if (e.count != 0 && e.count != 2) bad[e.face] = 1;  // a border, or shared by three
  }

  // The surfaces, their faces side by side (counting sort by root).
  std::vector<int> root(n), size(n, 0);
  std::vector<uint8_t> bad_root(n, 0);
  for (int j = 0; j < n; ++j) {
    root[j] = find_root(parent, j);
    ++size[root[j]];
    bad_root[root[j]] |= bad[j];
  }
  std::vector<int> start(n + 1, 0);
  for (int j = 0; j < n; ++j) start[j + 1] = start[j] + size[j];
  std::vector<int> members(n), fill(start.begin(), start.end() - 1);
  for (int j = 0; j < n; ++j) members[fill[root[j]]++] = j;

  std::vector<int> verts;
  for (int r = 0; r < n; ++r) {
    if (bad_root[r] || size[r] < 4 || size[r] > kMaxSolidFaces) continue;
    const int* fs = &members[start[r]];
    verts.clear();
    for (int q = 0; q < size[r]; ++q) {
      for (int c = first[fs[q]]; c < first[fs[q] + 1]; ++c) verts.push_back(corner[c]);
    }
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    Aabb box;
    double far = 0;
    for (int v : verts) {
      box.extend(ids.points[v]);
      far = std::max(far, max_component(glm::abs(ids.points[v])));
    }
    // The enclosed volume (divergence theorem over fans of the faces): its
    // sign says whether the faces' own normals point out of the solid.
    double volume = 0;
    for (int q = 0; q < size[r]; ++q) {
      const std::vector<Vec3>& vs = poly(fs[q]).verts;
      for (size_t k = 1; k + 1 < vs.size(); ++k)
        volume += glm::dot(vs[0], glm::cross(vs[k], vs[k + 1]));
    }
    volume /= 6.0;
    const double diag = glm::length(box.hi - box.lo);
    if (!(std::abs(volume) > 1e-9 * diag * diag * diag)) continue;  // flat: two sides of a sheet
    const double sign = volume > 0 ? 1.0 : -1.0;
    // Convex: no vertex outside any face's plane.
    const double tol = 1e-9 * diag + 1e-12 * far;
    bool convex = true;
    for (int q = 0; q < size[r] && convex; ++q) {
      const PolygonPrim& p = poly(fs[q]);
      for (int v : verts) {
        if (sign * (glm::dot(p.normal, ids.points[v]) - p.offset) > tol) {
          convex = false;
          break;
        }
      }
    }
    if (!convex) continue;
    for (int q = 0; q < size[r]; ++q) out.faces.push_back(polys[fs[q]]);
    out.first.push_back(static_cast<int>(out.faces.size()));
    out.sign.push_back(sign);
    out.tolerance.push_back(tol);
  }
  return out;
}

namespace {

// The polygon of solid face q.
const PolygonPrim& solid_face(const PrimitiveSet& set, const ClosedSolids& solids, int s, int q) {
  return set.polygons[set.prims[solids.faces[solids.first[s] + q]].index];
}

// Every face of solid s stops light (eq. (2)).
bool solid_opaque(const ClosedSolids& solids, int s, const std::vector<uint8_t>& stops_light) {
  for (int i = solids.first[s]; i < solids.first[s + 1]; ++i)
    if (!stops_light[solids.faces[i]]) return false;
  return true;
}

// The point lies outside convex solid s: in front of one of its faces.
bool outside_solid(const PrimitiveSet& set, const ClosedSolids& solids, int s, const Vec3& point) {
  const int nf = solids.first[s + 1] - solids.first[s];
  for (int q = 0; q < nf; ++q) {
    const PolygonPrim& f = solid_face(set, solids, s, q);
    if (solids.sign[s] * (glm::dot(f.normal, point) - f.offset) > 0) return true;
  }
  return false;
}

}  // namespace

std::vector<uint8_t> ray_culls(const PrimitiveSet& set, const ClosedSolids& solids,
                               const CameraFrame& cam, double z_near,
                               const std::vector<Light>& lights,
                               const std::vector<uint8_t>& stops_light) {
  std::vector<uint8_t> culls(set.prims.size(), 0);
  const int nl = std::min(static_cast<int>(lights.size()), kCullLights);
  for (int s = 0; s < solids.count(); ++s) {
    const int* fs = &solids.faces[solids.first[s]];
    const int nf = solids.first[s + 1] - solids.first[s];
    const double sign = solids.sign[s];
    auto poly = [&](int q) -> const PolygonPrim& { return solid_face(set, solids, s, q); };
    bool beyond = true;
    for (int q = 0; q < nf; ++q) {
      for (const Vec3& p : poly(q).verts) beyond = beyond && beyond_near(cam, z_near, p);
    }
    if (beyond) {
      for (int q = 0; q < nf; ++q) {
        if (faces_away(sign * poly(q).normal, sign * poly(q).offset, cam.from))
          culls[fs[q]] |= kCullEye;
      }
    }
    if (!solid_opaque(solids, s, stops_light)) continue;
    for (int j = 0; j < nl; ++j) {
      const Vec3& light = lights[j].position;
      if (!outside_solid(set, solids, s, light)) continue;
      for (int q = 0; q < nf; ++q) {
        if (faces_away(sign * poly(q).normal, sign * poly(q).offset, light))
          culls[fs[q]] |= cull_light(j);
      }
    }
  }
  return culls;
}

std::vector<OwnSolid> own_solids(const PrimitiveSet& set, const ClosedSolids& solids,
                                 const std::vector<Light>& lights,
                                 const std::vector<uint8_t>& stops_light, double eps) {
  std::vector<OwnSolid> out;
  const int nl = std::min(static_cast<int>(lights.size()), kOwnSolidLights);
  // How far in front of a face light j must lie (own_solid_skip).
  double margin[kOwnSolidLights];
  for (int j = 0; j < nl; ++j) margin[j] = eps + 1e-12 * glm::length(lights[j].position);
  for (int s = 0; s < solids.count(); ++s) {
    const int* fs = &solids.faces[solids.first[s]];
    const int nf = solids.first[s + 1] - solids.first[s];
    const auto [lo, hi] = std::minmax_element(fs, fs + nf);
    if (*hi - *lo + 1 != nf || !solid_opaque(solids, s, stops_light)) continue;
    // Its vertices may stand up to its tolerance outside a face's plane:
    // far below eps but in a scene of coordinates beyond about 1e8, where
    // eps stops growing with the scene.
    if (!(10.0 * solids.tolerance[s] < eps)) continue;
    for (int q = 0; q < nf; ++q) {
      const PolygonPrim& f = solid_face(set, solids, s, q);
      OwnSolid o;
      o.first = *lo;
      o.count = static_cast<int16_t>(nf);
      for (int j = 0; j < nl; ++j) {
        // In front of the face by the margin, so outside the solid too.
        if (solids.sign[s] * (glm::dot(f.normal, lights[j].position) - f.offset) > margin[j])
          o.lights |= uint8_t(1u << j);
      }
      if (o.lights == 0) continue;
      if (out.empty()) out.resize(set.prims.size());
      out[fs[q]] = o;
    }
  }
  return out;
}

bool convex_hides_back_faces(const ConvexPrim& c, const CameraFrame& cam, double z_near) {
  for (const std::vector<Vec3>& face : c.faces) {
    for (const Vec3& p : face) {
      if (!beyond_near(cam, z_near, p)) return false;
    }
  }
  return true;
}

}  // namespace locus
