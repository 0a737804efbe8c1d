// Convex polyhedron builders (polyhedron.h). Every face runs
// counter-clockwise seen from outside, the form the renderer turns into
// outward half-spaces.
#include "common/scene/polyhedron.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <unordered_map>

namespace locus {

Polyhedron make_box(const Vec3& lo_in, const Vec3& hi_in) {
  const Vec3 lo = glm::min(lo_in, hi_in), hi = glm::max(lo_in, hi_in);
  Polyhedron p;
  // Vertex i has x from bit 0, y from bit 1, z from bit 2 (0: lo, 1: hi).
  for (int i = 0; i < 8; ++i) {
    p.vertices.emplace_back(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  }
  p.faces = {{0, 4, 6, 2}, {1, 3, 7, 5},   // -x, +x
             {0, 1, 5, 4}, {2, 6, 7, 3},   // -y, +y
             {0, 2, 3, 1}, {4, 5, 7, 6}};  // -z, +z
  return p;
}

Polyhedron make_prism(int sides, double radius, const Vec3& base, const Vec3& apex,
                      double twist_degrees) {
  const Vec3 w = glm::normalize(apex - base);
  // (u, v, w) right-handed, so increasing angles run counter-clockwise seen
  // from the apex side.
  const Vec3 u = any_perpendicular(w);
  const Vec3 v = glm::cross(w, u);
  Polyhedron p;
  for (const Vec3& centre : {base, apex}) {
    for (int i = 0; i < sides; ++i) {
      const double a = glm::radians(twist_degrees) + 2.0 * std::numbers::pi * i / sides;
      p.vertices.push_back(centre + radius * (std::cos(a) * u + std::sin(a) * v));
    }
  }
  std::vector<int> bottom, top;
  for (int i = 0; i < sides; ++i) {
    bottom.push_back(sides - 1 - i);  // seen from below: reversed
    top.push_back(sides + i);
    const int j = (i + 1) % sides;
    p.faces.push_back({i, j, sides + j, sides + i});
  }
  p.faces.push_back(bottom);
  p.faces.push_back(top);
  return p;
}

namespace {

// Quickhull (Barber, Dobkin, Huhdanpaa 1996) over triangles, then coplanar
// triangles merged into polygons. Points within `eps` of a plane count as on
// it, which is what keeps the incremental construction consistent for
// degenerate input such as a cube with points on its faces.
class HullBuilder {
 public:
  explicit HullBuilder(const std::vector<Vec3>& points) : pts_(points) {
    double scale = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
      double m = 0.0;
      for (const Vec3& p : pts_) m = std::max(m, std::abs(p[axis]));
      scale += m;
    }
    eps_ = 1e-10 * scale;
  }

  std::optional<Polyhedron> build() {
    if (pts_.size() < 4) return std::nullopt;
    for (const Vec3& p : pts_) {
      if (!is_finite(p)) return std::nullopt;
    }
    if (!make_simplex()) return std::nullopt;
    // Faces made while processing are appended and reached by this same
    // pass; only new faces ever receive outside points.
    for (size_t f = 0; f < tris_.size(); ++f) {
      if (tris_[f].alive && !tris_[f].outside.empty()) {
        if (!add_point(static_cast<int>(f))) return std::nullopt;
      }
    }
    return merge_faces();
  }

 private:
  struct Tri {
    std::array<int, 3> v;
    Vec3 normal;  // unit, outward
    double offset = 0.0;
    std::vector<int> outside;  // points farther than eps in front
    bool alive = true;
  };

  static uint64_t key(int a, int b) {
    return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
  }
  double distance(const Tri& t, int p) const { return glm::dot(t.normal, pts_[p]) - t.offset; }
  int owner(int a, int b) const {
    auto it = edge_owner_.find(key(a, b));
    return it == edge_owner_.end() ? -1 : it->second;
  }

  bool add_tri(int a, int b, int c) {
    const Vec3 n = glm::cross(pts_[b] - pts_[a], pts_[c] - pts_[a]);
    const double len = glm::length(n);
    if (!(len > 0.0)) return false;
    Tri t;
    t.v = {a, b, c};
    t.normal = n / len;
    t.offset = glm::dot(t.normal, pts_[a]);
    const int index = static_cast<int>(tris_.size());
    for (int k = 0; k < 3; ++k) edge_owner_[key(t.v[k], t.v[(k + 1) % 3])] = index;
    tris_.push_back(std::move(t));
    return true;
  }

  // Give each point to the face it lies farthest in front of, if any.
  void assign(const std::vector<int>& points, const std::vector<int>& faces) {
    for (int p : points) {
      double best = eps_;
      int best_face = -1;
      for (int f : faces) {
        const double d = distance(tris_[f], p);
        if (d > best) {
          best = d;
          best_face = f;
        }
      }
      if (best_face >= 0) tris_[best_face].outside.push_back(p);
    }
  }

  bool make_simplex() {
    const int n = static_cast<int>(pts_.size());
    std::array<int, 6> extremes{};
    for (int i = 0; i < n; ++i) {
      for (int axis = 0; axis < 3; ++axis) {
        if (pts_[i][axis] < pts_[extremes[2 * axis]][axis]) extremes[2 * axis] = i;
        if (pts_[i][axis] > pts_[extremes[2 * axis + 1]][axis]) extremes[2 * axis + 1] = i;
      }
    }
    int i0 = 0, i1 = 0;
    double best = -1.0;
    for (int a : extremes) {
      for (int b : extremes) {
        const double d = glm::length(pts_[a] - pts_[b]);
        if (d > best) {
          best = d;
          i0 = a;
          i1 = b;
        }
      }
    }
    if (best <= eps_) return false;
    const Vec3 dir = glm::normalize(pts_[i1] - pts_[i0]);
    int i2 = -1;
    best = eps_;
    for (int i = 0; i < n; ++i) {
      const double d = glm::length(glm::cross(pts_[i] - pts_[i0], dir));
      if (d > best) {
        best = d;
        i2 = i;
      }
    }
    if (i2 < 0) return false;
    const Vec3 normal = glm::normalize(glm::cross(pts_[i1] - pts_[i0], pts_[i2] - pts_[i0]));
    int i3 = -1;
    best = eps_;
    for (int i = 0; i < n; ++i) {
      const double d = std::abs(glm::dot(normal, pts_[i] - pts_[i0]));
      if (d > best) {
        best = d;
        i3 = i;
      }
    }
    if (i3 < 0) return false;

    const std::array<int, 4> s{i0, i1, i2, i3};
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> t{};
      int k = 0;
      for (int j = 0; j < 4; ++j) {
        if (j != skip) t[k++] = s[j];
      }
      // Orient away from the fourth vertex.
      const Vec3 n = glm::cross(pts_[t[1]] - pts_[t[0]], pts_[t[2]] - pts_[t[0]]);
      if (glm::dot(n, pts_[s[skip]] - pts_[t[0]]) > 0.0) std::swap(t[1], t[2]);
      if (!add_tri(t[0], t[1], t[2])) return false;
    }
    std::vector<int> rest;
    for (int i = 0; i < n; ++i) {
      if (i != i0 && i != i1 && i != i2 && i != i3) rest.push_back(i);
    }
    assign(rest, {0, 1, 2, 3});
    return true;
  }

  // One Quickhull step: the farthest outside point of face f replaces the
  // faces it sees by a cone of new faces over their horizon.
  bool add_point(int f) {
    const std::vector<int>& outside = tris_[f].outside;
    const int eye = *std::max_element(outside.begin(), outside.end(), [&](int a, int b) {
      return distance(tris_[f], a) < distance(tris_[f], b);
    });

    // Visible faces by flood fill from f, so that the visible set is
    // connected even where eps makes visibility inexact.
    std::vector<int> visible{f}, horizon;  // horizon: pairs a, b
    std::vector<int> stack{f};
    visit_.resize(tris_.size(), 0);
    ++stamp_;
    visit_[f] = stamp_;
    while (!stack.empty()) {
      const int t = stack.back();
      stack.pop_back();
      for (int k = 0; k < 3; ++k) {
        const int a = tris_[t].v[k], b = tris_[t].v[(k + 1) % 3];
        const int g = owner(b, a);
        if (g < 0) return false;
        if (visit_[g] == stamp_) continue;
        if (distance(tris_[g], eye) > eps_) {
          visit_[g] = stamp_;
          visible.push_back(g);
          stack.push_back(g);
        } else {
          horizon.push_back(a);
          horizon.push_back(b);
        }
      }
    }

    std::vector<int> orphans;
    for (int t : visible) {
      Tri& tri = tris_[t];
      tri.alive = false;
      for (int k = 0; k < 3; ++k) edge_owner_.erase(key(tri.v[k], tri.v[(k + 1) % 3]));
      for (int p : tri.outside) {
        if (p != eye) orphans.push_back(p);
      }
      tri.outside.clear();
      tri.outside.shrink_to_fit();
    }
    std::vector<int> made;
    for (size_t h = 0; h < horizon.size(); h += 2) {
      made.push_back(static_cast<int>(tris_.size()));
      if (!add_tri(horizon[h], horizon[h + 1], eye)) return false;
    }
    assign(orphans, made);
    return true;
  }

  int find(std::vector<int>& parent, int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }

  std::optional<Polyhedron> merge_faces() {
    const int nt = static_cast<int>(tris_.size());
    std::vector<int> parent(nt);
    std::iota(parent.begin(), parent.end(), 0);
    auto opposite = [&](const Tri& t, int a, int b) {
      for (int v : t.v) {
        if (v != a && v != b) return v;
      }
      return t.v[0];
    };
    for (int t = 0; t < nt; ++t) {
      if (!tris_[t].alive) continue;
      for (int k = 0; k < 3; ++k) {
        const int a = tris_[t].v[k], b = tris_[t].v[(k + 1) % 3];
        const int g = owner(b, a);
        if (g < 0 || !tris_[g].alive) return std::nullopt;  // not closed
        if (g < t) continue;
        if (std::abs(distance(tris_[t], opposite(tris_[g], a, b))) <= eps_ &&
            std::abs(distance(tris_[g], opposite(tris_[t], a, b))) <= eps_) {
          parent[find(parent, g)] = find(parent, t);
        }
      }
    }

    // Each group's boundary, walked as one loop: a convex face.
    std::unordered_map<int, std::unordered_map<int, int>> next_by_group;  // group -> (a -> b)
    std::vector<int> group_order;
    for (int t = 0; t < nt; ++t) {
      if (!tris_[t].alive) continue;
      const int group = find(parent, t);
      if (!next_by_group.count(group)) group_order.push_back(group);
      auto& next = next_by_group[group];
      for (int k = 0; k < 3; ++k) {
        const int a = tris_[t].v[k], b = tris_[t].v[(k + 1) % 3];
        if (find(parent, owner(b, a)) == group) continue;
        if (!next.emplace(a, b).second) return std::nullopt;  // pinched face
      }
    }
    std::vector<std::vector<int>> loops;
    for (int group : group_order) {
      const auto& next = next_by_group[group];
      if (next.empty()) return std::nullopt;
      std::vector<int> loop;
      int at = next.begin()->first;
      do {
        loop.push_back(at);
        auto it = next.find(at);
        if (it == next.end() || loop.size() > next.size()) return std::nullopt;
        at = it->second;
      } while (at != loop[0]);
      if (loop.size() != next.size()) return std::nullopt;  // several loops: not a disc
      loops.push_back(std::move(loop));
    }

    // A vertex on only two faces lies on an edge between them (it was on
    // the hull when added, then a later point made it redundant). Dropping
    // it from both loops keeps the edges matched.
    std::vector<int> face_count(pts_.size(), 0);
    for (const auto& loop : loops) {
      for (int v : loop) ++face_count[v];
    }
    Polyhedron out;
    std::vector<int> new_index(pts_.size(), -1);
    for (const auto& loop : loops) {
      std::vector<int> face;
      for (int v : loop) {
        if (face_count[v] < 3) continue;
        if (new_index[v] < 0) {
          new_index[v] = static_cast<int>(out.vertices.size());
          out.vertices.push_back(pts_[v]);
        }
        face.push_back(new_index[v]);
      }
      if (face.size() < 3) return std::nullopt;
      out.faces.push_back(std::move(face));
    }
    if (out.faces.size() < 4) return std::nullopt;
    return out;
  }

  const std::vector<Vec3>& pts_;
  double eps_ = 0.0;
  std::vector<Tri> tris_;
  std::unordered_map<uint64_t, int> edge_owner_;  // directed edge -> face
  std::vector<int> visit_;
  int stamp_ = 0;
};

}  // namespace

std::optional<Polyhedron> make_hull(const std::vector<Vec3>& points) {
  return HullBuilder(points).build();
}

}  // namespace locus
