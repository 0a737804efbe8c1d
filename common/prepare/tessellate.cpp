#include "common/prepare/tessellate.h"

#include <algorithm>
#include <cmath>
#include <map>

namespace locus {
namespace {

// Bernstein polynomials of degree 3 and their derivatives.
std::array<double, 4> bernstein(double t) {
  const double s = 1.0 - t;
  return {s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t};
}

std::array<double, 4> bernstein_derivative(double t) {
  const double s = 1.0 - t;
  return {-3.0 * s * s, 3.0 * s * s - 6.0 * t * s, 6.0 * t * s - 3.0 * t * t, 3.0 * t * t};
}

// sum_ij bv[i] bu[j] P_ij
Vec3 combine(const BezierPatch& p, const std::array<double, 4>& bu,
             const std::array<double, 4>& bv) {
  Vec3 out(0.0);
  for (int i = 0; i < 4; ++i) {
    Vec3 row(0.0);
    for (int j = 0; j < 4; ++j) row += bu[j] * p.points[4 * i + j];
    out += bv[i] * row;
  }
  return out;
}

double net_size(const BezierPatch& p) {
  Vec3 lo = p.points[0], hi = p.points[0];
  for (const Vec3& q : p.points) {
    lo = glm::min(lo, q);
    hi = glm::max(hi, q);
  }
  return glm::length(hi - lo);
}

// A point of a Bezier curve by de Casteljau, with (1 - t) a + t b so that
// t = 0 and t = 1 give the end points bit for bit: patches meeting at a
// corner share that vertex exactly.
Vec3 curve_point(const std::array<Vec3, 4>& c, double t) {
  const double s = 1.0 - t;
  Vec3 a = s * c[0] + t * c[1], b = s * c[1] + t * c[2], d = s * c[2] + t * c[3];
  a = s * a + t * b;
  b = s * b + t * d;
  return s * a + t * b;
}

// The four boundary curves of a patch, each running with increasing u or v:
// 0: v = 0, 1: u = 1, 2: v = 1, 3: u = 0.
std::array<Vec3, 4> boundary(const BezierPatch& p, int side) {
  std::array<Vec3, 4> c;
  for (int k = 0; k < 4; ++k) {
    switch (side) {
      case 0:
        c[k] = p.points[k];
        break;
      case 1:
        c[k] = p.points[4 * k + 3];
        break;
      case 2:
        c[k] = p.points[12 + k];
        break;
      default:
        c[k] = p.points[4 * k];
        break;
    }
  }
  return c;
}

bool lex_less(const Vec3& a, const Vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// An edge as both of its patches see it: the curve in one canonical
// direction, so that neighbours agree on its key and on its sample points.
using EdgeKey = std::array<double, 12>;
struct Edge {
  EdgeKey key;
  bool reversed = false;  // the patch runs the other way along it
};

Edge edge_of(const std::array<Vec3, 4>& c) {
  Edge e;
  e.reversed = lex_less(c[3], c[0]) || (c[3] == c[0] && lex_less(c[2], c[1]));
  for (int k = 0; k < 4; ++k) {
    const Vec3& q = c[e.reversed ? 3 - k : k];
    e.key[3 * k] = q.x;
    e.key[3 * k + 1] = q.y;
    e.key[3 * k + 2] = q.z;
  }
  return e;
}

std::array<Vec3, 4> curve_of(const EdgeKey& k) {
  return {Vec3(k[0], k[1], k[2]), Vec3(k[3], k[4], k[5]), Vec3(k[6], k[7], k[8]),
          Vec3(k[9], k[10], k[11])};
}

// Appends one patch's triangles to `out`: the interior grid of rates
// (nu, nv), stitched to the four boundary curves sampled at edge_rate[side]
// segments each (docs/tessellation.md "No cracks").
class PatchMesher {
 public:
  PatchMesher(const BezierPatch& p, int patch, int nu, int nv, SurfaceTessellation& out)
      : p_(p), patch_(patch), nu_(nu), nv_(nv), out_(out) {}

  void mesh(const std::array<std::vector<Vec3>, 4>& sides) {
    // Interior grid (i, j) for i in [1, nu - 1], j in [1, nv - 1].
    inner_.assign(static_cast<size_t>((nu_ - 1) * (nv_ - 1)), -1);
    for (int j = 1; j < nv_; ++j) {
      for (int i = 1; i < nu_; ++i) {
        const double u = static_cast<double>(i) / nu_, v = static_cast<double>(j) / nv_;
        inner_[index(i, j)] = vertex(bezier_point(p_, u, v), u, v);
      }
    }
    for (int j = 1; j + 1 < nv_; ++j) {
      for (int i = 1; i + 1 < nu_; ++i) {
        const int a = inner_[index(i, j)], b = inner_[index(i + 1, j)];
        const int c = inner_[index(i + 1, j + 1)], d = inner_[index(i, j + 1)];
        triangle(a, b, c);
        triangle(a, c, d);
      }
    }
    for (int side = 0; side < 4; ++side) stitch(side, sides[side]);
  }

 private:
  size_t index(int i, int j) const { return static_cast<size_t>((j - 1) * (nu_ - 1) + (i - 1)); }

  int vertex(const Vec3& position, double u, double v) {
    out_.mesh.positions.push_back(position);
    out_.mesh.normals.push_back(bezier_normal(p_, u, v));
    out_.uv.emplace_back(u, v);
    out_.vertex_patch.push_back(patch_);
    return static_cast<int>(out_.mesh.positions.size()) - 1;
  }

  // Triangles with two equal corners (along a collapsed boundary row) have
  // nothing to show.
  void triangle(int a, int b, int c) {
    const auto& x = out_.mesh.positions;
    if (x[a] == x[b] || x[b] == x[c] || x[c] == x[a]) return;
    out_.mesh.triangles.push_back({a, b, c});
  }

  // (u, v) of the point at parameter t along a side, the sides running
  // counter-clockwise in the parameter plane: 0 is v = 0 from u = 0 to 1,
  // 1 is u = 1 upwards, 2 is v = 1 from u = 1 to 0, 3 is u = 0 downwards.
  static Vec2 side_uv(int side, double t) {
    switch (side) {
      case 0:
        return {t, 0.0};
      case 1:
        return {1.0, t};
      case 2:
        return {1.0 - t, 1.0};
      default:
        return {0.0, 1.0 - t};
    }
  }

  // The ring between a boundary curve (samples `outer`, in the side's
  // counter-clockwise order) and the interior grid's outermost row or
  // column along it: two sorted polylines zipped by parameter, so every
  // triangle spans at most one interior step across and along the side.
  void stitch(int side, const std::vector<Vec3>& outer) {
    const int m = static_cast<int>(outer.size()) - 1;
    std::vector<int> o(outer.size());
    for (int a = 0; a <= m; ++a) {
      const double t = static_cast<double>(a) / m;
      const Vec2 uv = side_uv(side, t);
      o[a] = vertex(outer[a], uv.x, uv.y);
    }
    const int n = (side % 2 == 0) ? nu_ : nv_;  // interior steps along this side
    std::vector<int> in(static_cast<size_t>(n - 1));
    for (int b = 0; b + 1 < n; ++b) {
      const int k = b + 1;
      switch (side) {
        case 0:
          in[b] = inner_[index(k, 1)];
          break;
        case 1:
          in[b] = inner_[index(nu_ - 1, k)];
          break;
        case 2:
          in[b] = inner_[index(nu_ - k, nv_ - 1)];
          break;
        default:
          in[b] = inner_[index(1, nv_ - k)];
          break;
      }
    }
    const int last = n - 2;
    int a = 0, b = 0;
    while (a < m || b < last) {
      // Outer step ends at a+1 / m, inner at (b+2) / n: take the nearer.
      const bool outer_step =
          b == last || (a < m && static_cast<double>(a + 1) / m <= static_cast<double>(b + 2) / n);
      if (outer_step) {
        triangle(o[a], o[a + 1], in[b]);
        ++a;
      } else {
        triangle(o[a], in[b + 1], in[b]);
        ++b;
      }
    }
  }

  const BezierPatch& p_;
  int patch_;
  int nu_, nv_;
  SurfaceTessellation& out_;
  std::vector<int> inner_;
};

}  // namespace

Vec3 bezier_point(const BezierPatch& p, double u, double v) {
  return combine(p, bernstein(u), bernstein(v));
}

Vec3 bezier_normal(const BezierPatch& p, double u, double v) {
  const double size = net_size(p);
  // Nudged towards the patch centre until dS/du x dS/dv is well defined: at
  // a collapsed boundary row it vanishes, but its direction has a limit
  // from inside, which a step of 1e-6 reaches to within ~1e-6 radians.
  for (double h : {0.0, 1e-6, 1e-3, 1e-1}) {
    const double uu = u + (0.5 - u) * h, vv = v + (0.5 - v) * h;
    const Vec3 du = combine(p, bernstein_derivative(uu), bernstein(vv));
    const Vec3 dv = combine(p, bernstein(uu), bernstein_derivative(vv));
    const Vec3 n = glm::cross(du, dv);
    const double len = glm::length(n);
    if (len > 1e-12 * size * size && std::isfinite(len)) return n / len;
  }
  return Vec3(0, 0, 1);
}

TessView make_tess_view(const Scene& scene, double tolerance) {
  TessView view;
  const Camera& c = scene.camera;
  view.eye = c.from;
  view.w = glm::normalize(c.at - c.from);
  view.u = glm::normalize(glm::cross(view.w, c.up));
  view.v = glm::cross(view.u, view.w);
  view.tan_half = std::tan(glm::radians(c.angle) * 0.5);
  view.aspect = static_cast<double>(c.width) / c.height;
  view.hither = c.hither;
  view.height = c.height;
  view.tolerance = tolerance;
  for (const Object& o : scene.objects) {
    if (o.material < 0 || o.material >= static_cast<int>(scene.materials.size())) continue;
    const Material& m = scene.materials[o.material];
    view.mirrors = view.mirrors || m.ks > 0.0 || m.t > 0.0;
  }
  return view;
}

PatchScale patch_scale(const TessView& view, const BezierPatch& p) {
  // Pixels per unit of lateral offset at unit depth (SHADING.md camera:
  // the image is 2 tan(angle/2) high at depth 1).
  const double focal = view.height / (2.0 * view.tan_half);
  // A displacement d at a point of depth z moves its image by at most
  // |d| focal k / z while the moved point stays in the frustum, k being the
  // secant of the frustum corner's angle off the axis (docs/tessellation.md).
  const double k =
      std::sqrt(1.0 + view.tan_half * view.tan_half * (1.0 + view.aspect * view.aspect));
  double zmin = 1e300;
  bool out_right = true, out_left = true, out_top = true, out_bottom = true, behind = true;
  Vec3 lo(1e300), hi(-1e300);
  for (const Vec3& q : p.points) {
    const Vec3 d = q - view.eye;
    const double z = glm::dot(d, view.w), x = glm::dot(d, view.u), y = glm::dot(d, view.v);
    zmin = std::min(zmin, z);
    behind = behind && z < view.hither;
    out_right = out_right && x > view.tan_half * view.aspect * z;
    out_left = out_left && -x > view.tan_half * view.aspect * z;
    out_top = out_top && y > view.tan_half * z;
    out_bottom = out_bottom && -y > view.tan_half * z;
    lo = glm::min(lo, q);
    hi = glm::max(hi, q);
  }
  // Nearest point of the control net's box to the eye: a lower bound on the
  // distance of every surface point (the patch lies in its net's hull).
  const double dist = glm::length(glm::max(glm::max(lo - view.eye, view.eye - hi), Vec3(0.0)));
  // No depth below this counts: a patch through the eye plane is cut to
  // the rate cap instead of infinitely finely.
  const double floor =
      std::max({view.hither, 1e-9 * (glm::length(view.eye) + glm::length(hi - lo)), 1e-300});
  PatchScale s;
  s.in_view = !(behind || out_right || out_left || out_top || out_bottom);
  // Seen in a plane mirror, a point at distance d from the eye appears at
  // depth >= d / k along the eye ray of a pixel in the frustum: one more k.
  const double reflected = focal * k * k / std::max(dist, floor);
  if (s.in_view) {
    s.pixels_per_unit = focal * k / std::max(zmin, floor);
    if (view.mirrors) s.pixels_per_unit = std::max(s.pixels_per_unit, reflected);
  } else {
    s.pixels_per_unit = view.mirrors ? reflected : reflected / (k * kOffscreenTolFactor);
  }
  return s;
}

std::array<int, 2> patch_rates(const BezierPatch& p, double pixels_per_unit, double tolerance) {
  // Bounds on |S_uu|, |S_vv|, |S_uv| over the patch: the second derivatives
  // are Bezier patches whose control points are 6x the net's second
  // differences (9x the mixed ones), so their largest norm bounds them.
  double a = 0, b = 0, c = 0;
  const auto& P = p.points;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 2; ++j) {
      a = std::max(a, glm::length(P[4 * i + j + 2] - 2.0 * P[4 * i + j + 1] + P[4 * i + j]));
      b = std::max(b, glm::length(P[4 * (j + 2) + i] - 2.0 * P[4 * (j + 1) + i] + P[4 * j + i]));
    }
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      c = std::max(c, glm::length(P[4 * (i + 1) + j + 1] - P[4 * (i + 1) + j] - P[4 * i + j + 1] +
                                  P[4 * i + j]));
    }
  }
  a *= 6.0;
  b *= 6.0;
  c *= 9.0;
  // A triangle whose vertices span at most du, dv in parameters deviates
  // from the surface by at most (a du^2 + 2 c du dv + b dv^2) / 8 (the
  // remainder of linear interpolation); 2 c du dv <= c (du^2 + dv^2), and
  // half the tolerance goes to each direction, which minimises nu * nv.
  auto rate = [&](double second) {
    const double n = std::ceil(std::sqrt(pixels_per_unit * second / (4.0 * tolerance)));
    if (!(n < kMaxTessRate)) return kMaxTessRate;  // also NaN
    return std::max(2, static_cast<int>(n));
  };
  return {rate(a + c), rate(b + c)};
}

SurfaceTessellation tessellate_surface(const std::vector<BezierPatch>& patches,
                                       const TessView& view) {
  SurfaceTessellation out;
  const int n = static_cast<int>(patches.size());
  // Rates per patch, then per shared edge the largest rate any patch along
  // it needs, so both neighbours sample it alike.
  std::map<EdgeKey, int> edge_rate;
  out.rates.resize(n);
  int64_t estimate = 0;
  for (int k = 0; k < n; ++k) {
    const PatchScale s = patch_scale(view, patches[k]);
    out.rates[k] = patch_rates(patches[k], s.pixels_per_unit, view.tolerance);
    estimate += 2 * int64_t{out.rates[k][0]} * out.rates[k][1];
  }
  if (estimate > view.max_triangles) {
    const double f = std::sqrt(static_cast<double>(view.max_triangles) / estimate);
    for (auto& r : out.rates) {
      for (int& x : r) x = std::max(2, static_cast<int>(x * f));
    }
  }
  for (int k = 0; k < n; ++k) {
    for (int side = 0; side < 4; ++side) {
      // A collapsed row is sampled at its patch's rate too: its samples
      // coincide, but their parameters keep the fan next to it within one
      // step in u and v, where the bound holds.
      int& e = edge_rate[edge_of(boundary(patches[k], side)).key];
      e = std::max(e, out.rates[k][side % 2]);
    }
  }
  for (int k = 0; k < n; ++k) {
    std::array<std::vector<Vec3>, 4> sides;
    for (int side = 0; side < 4; ++side) {
      const std::array<Vec3, 4> c = boundary(patches[k], side);
      const Edge e = edge_of(c);
      const int m = edge_rate[e.key];
      // Samples along the canonical curve, then in this side's
      // counter-clockwise order (sides 2 and 3 run against u and v).
      const std::array<Vec3, 4> canonical = curve_of(e.key);
      std::vector<Vec3> pts(static_cast<size_t>(m + 1));
      for (int i = 0; i <= m; ++i) pts[i] = curve_point(canonical, static_cast<double>(i) / m);
      if (e.reversed != (side >= 2)) std::reverse(pts.begin(), pts.end());
      sides[side] = std::move(pts);
    }
    PatchMesher(patches[k], k, out.rates[k][0], out.rates[k][1], out).mesh(sides);
  }
  return out;
}

Scene tessellate_scene(Scene scene, double tolerance) {
  const TessView view = make_tess_view(scene, tolerance);
  for (Object& o : scene.objects) {
    const auto* surface = std::get_if<BezierSurface>(&o.shape);
    if (!surface) continue;
    std::vector<BezierPatch> world = surface->patches;
    if (o.world_from_object != Mat4(1.0)) {
      for (BezierPatch& p : world) {
        for (Vec3& q : p.points) q = transform_point(o.world_from_object, q);
      }
    }
    o.shape = std::move(tessellate_surface(world, view).mesh);
    o.world_from_object = Mat4(1.0);
  }
  return scene;
}

}  // namespace locus
