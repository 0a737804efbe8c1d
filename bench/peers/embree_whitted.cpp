// locus-embree-whitted: a minimal Whitted ray tracer on Intel Embree 3, the
// peer of `locus render --method raytrace --spp 1` for the per-ray kernel
// comparison (issue #27 item 2; bench/peers/kernel.py, bench/peers/README.md
// "The ray kernel against Embree").
//
// Same rays as Locus: the scene is read by Locus's own loader and prepared
// by prepare_scene (camera frame, world-space primitives, the offset of
// secondary origins), one eye ray per pixel through its centre, a shadow ray
// to each light on the lit side, reflected and refracted rays under the same
// depth and weight cut-off (SHADING.md "Ray tree"), and the same shading
// (SHADING.md "Materials"), so the ray counts by kind agree with Locus's
// --stats. Only the search for the nearest surface and for occluders is
// Embree's:
// - triangles, and polygons cut into triangles (ear clipping: SPD gears'
//   faces are concave), as Embree triangle geometry, in float; the winner's
//   distance, barycentrics and normal are computed again in double;
// - spheres and cones (NFF cylinders and cones, open) as Embree user
//   geometry whose callbacks solve the quadric in double on the double ray
//   (exact hits, as Locus's);
// - shadow rays by rtcOccluded1; transparent surfaces (gears, mount) are
//   collected by the occlusion callbacks instead of stopping the ray and go
//   through eq. (3) (Locus's segment_transmittance).
// Locus's shadow cache and tie rule for coincident surfaces are not copied:
// neither changes which rays are cast.
//
// Usage: locus-embree-whitted SCENE [--size WxH] [-o IMAGE]
// Prints one JSON object: CPU and wall seconds of the render (the pixel
// loop alone: loading, Embree's device and its BVH build excluded), the
// build's, and the rays by kind, under the keys of Locus's --stats.
#include <embree3/rtcore.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/base/image.h"
#include "common/geometry/optics.h"
#include "common/base/cpu_time.h"
#include "common/prepare/prepared.h"
#include "common/scene/scene_io.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace {

// SHADING.md "Ray tree", as common/trace/raytrace.cpp.
constexpr int kMaxDepth = 5;
constexpr double kMinWeight = 1.0 / 512.0;

Color beer(const Color& q, double d) {
  return Color(std::exp(-q.x * d), std::exp(-q.y * d), std::exp(-q.z * d));
}

// Triangles of a planar polygon given by its outline dropped on two axes:
// a fan when it is convex, ear clipping otherwise.
std::vector<std::array<int, 3>> triangulate(const std::vector<Vec2>& pts) {
  const int n = static_cast<int>(pts.size());
  auto cross = [&](int a, int b, int c) {
    const Vec2 u = pts[b] - pts[a], v = pts[c] - pts[b];
    return u.x * v.y - u.y * v.x;
  };
  double area = 0;
  for (int i = 0, j = n - 1; i < n; j = i++) area += pts[j].x * pts[i].y - pts[i].x * pts[j].y;
  const double s = area >= 0 ? 1.0 : -1.0;
  std::vector<std::array<int, 3>> tris;
  bool convex = true;
  for (int i = 0; i < n && convex; ++i) convex = s * cross(i, (i + 1) % n, (i + 2) % n) >= 0;
  if (convex) {
    for (int i = 1; i + 1 < n; ++i) tris.push_back({0, i, i + 1});
    return tris;
  }
  std::vector<int> idx(n);
  for (int i = 0; i < n; ++i) idx[i] = i;
  auto inside = [&](int p, int a, int b, int c) {
    auto side = [&](int u, int v) {
      const Vec2 e = pts[v] - pts[u], w = pts[p] - pts[u];
      return s * (e.x * w.y - e.y * w.x);
    };
    return side(a, b) > 0 && side(b, c) > 0 && side(c, a) > 0;
  };
  while (idx.size() > 3) {
    const int m = static_cast<int>(idx.size());
    bool cut = false;
    for (int i = 0; i < m && !cut; ++i) {
      const int a = idx[(i + m - 1) % m], b = idx[i], c = idx[(i + 1) % m];
      if (s * cross(a, b, c) <= 0) continue;  // a reflex (or straight) corner
      bool ear = true;
      for (int k = 0; k < m && ear; ++k) {
        const int p = idx[k];
        if (p != a && p != b && p != c && inside(p, a, b, c)) ear = false;
      }
      if (!ear) continue;
      tris.push_back({a, b, c});
      idx.erase(idx.begin() + i);
      cut = true;
    }
    if (!cut) break;  // degenerate rest: a fan below
  }
  for (size_t i = 1; i + 1 < idx.size(); ++i) tris.push_back({idx[0], idx[i], idx[i + 1]});
  return tris;
}

// The nearest root in (tmin, tmax) of a sphere or an open cone, on the
// double ray; kInf if none. The same equations as intersect.cpp.
double sphere_t(const Sphere& s, const Vec3& o, const Vec3& d, double tmin, double tmax) {
  const Vec3 oc = o - s.center;
  double t0, t1;
  if (!solve_quadratic(glm::dot(d, d), 2.0 * glm::dot(oc, d),
                       glm::dot(oc, oc) - s.radius * s.radius, &t0, &t1)) {
    return kInf;
  }
  if (t0 > tmin && t0 < tmax) return t0;
  if (t1 > tmin && t1 < tmax) return t1;
  return kInf;
}

// Every root in (tmin, tmax) of an open cone into ts (at most 2); returns
// how many.
int cone_ts(const ConePrim& cp, const Vec3& o, const Vec3& d, double tmin, double tmax,
            double* ts) {
  const Cone& c = cp.c;
  const Vec3& a = cp.axis.a;
  const double k = cp.axis.k;
  const Vec3 co = o - c.base;
  const double da = glm::dot(d, a), ca = glm::dot(co, a);
  const Vec3 dp = d - da * a, cp_ = co - ca * a;
  const double rc = c.base_radius + k * ca;
  double t0, t1;
  if (!solve_quadratic(glm::dot(dp, dp) - k * k * da * da, 2.0 * (glm::dot(cp_, dp) - k * rc * da),
                       glm::dot(cp_, cp_) - rc * rc, &t0, &t1)) {
    return 0;
  }
  int n = 0;
  for (double t : {t0, t0 == t1 ? kInf : t1}) {
    if (!(t > tmin && t < tmax)) continue;
    const double s = ca + t * da;
    if (s < 0.0 || s > cp.axis.h) continue;
    ts[n++] = t;
  }
  return n;
}

Vec3 cone_normal(const ConePrim& cp, const Vec3& x) {
  const Vec3 v = x - cp.c.base;
  const double s = glm::dot(v, cp.axis.a);
  const Vec3 q = v - s * cp.axis.a;
  const double r = cp.c.base_radius + cp.axis.k * s;
  const Vec3 g = q - r * cp.axis.k * cp.axis.a;
  const double len = glm::length(g);
  return len > 0 ? g / len : cp.axis.a;
}

struct Peer;

// An Embree context carrying the double ray, for the callbacks.
struct RayContext {
  RTCIntersectContext base;  // first: Embree passes &base to the callbacks
  const Peer* peer = nullptr;
  Vec3 o, d;
  double tmin = 0, tmax = kInf;
  double quadric_t = kInf;  // the user geometry's accepted hit (nearest)
  unsigned quadric_prim = RTC_INVALID_GEOMETRY_ID;
  std::vector<Crossing>* crossings = nullptr;  // shadow rays: transparent ones
  std::vector<int>* crossed = nullptr;         // the Locus primitives they came from
};

// The three Embree geometries.
enum GeomId : unsigned { kOpaqueTris = 0, kClearTris = 1, kQuadrics = 2 };

struct Peer {
  const PreparedScene& ps;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<int> tri_prim[2];   // per Embree triangle: its Locus primitive
  std::vector<int> quadric_prim;  // per user-geometry primitive
  std::vector<bool> prim_clear;   // per Locus primitive: T > 0
  bool any_clear = false;
  Stats stats;

  explicit Peer(const PreparedScene& p) : ps(p) {}
  ~Peer() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  const Material& material_of(int prim) const {
    return ps.scene.materials[ps.scene.objects[ps.prims.prims[prim].object].material];
  }

  // The crossing of Locus primitive `prim` (a triangle or a polygon) that
  // Embree found near float distance tf, in double.
  Crossing flat_crossing(int prim, const Vec3& o, const Vec3& d, float tf, float u, float v) const {
    const PrimRef& ref = ps.prims.prims[prim];
    Crossing c;
    c.leaf = ref.object;
    if (ref.kind == PrimKind::kPolygon) {
      const PolygonPrim& p = ps.prims.polygons[ref.index];
      const double den = glm::dot(p.normal, d);
      c.t = den != 0.0 ? (p.offset - glm::dot(p.normal, o)) / den : tf;
      c.normal = p.normal;
      return c;
    }
    const TrianglePrim& tr = ps.prims.triangles[ref.index];
    const Vec3 pv = glm::cross(d, tr.e2);
    const double det = glm::dot(tr.e1, pv);
    c.normal = tr.normal;
    c.tri = ref.index;
    if (det == 0.0) {
      c.t = tf, c.u = u, c.v = v;
      return c;
    }
    const double inv = 1.0 / det;
    const Vec3 tv = o - tr.p0;
    const Vec3 qv = glm::cross(tv, tr.e1);
    c.u = glm::dot(tv, pv) * inv;
    c.v = glm::dot(d, qv) * inv;
    c.t = glm::dot(tr.e2, qv) * inv;
    return c;
  }

  Status build(bool robust);
  std::optional<SurfaceHit> nearest(const Vec3& o, const Vec3& d, double tmin);
  Color transmittance(const Vec3& p, const Vec3& ng, int light);
  Color trace(const Vec3& o, const Vec3& d, double tmin, int depth, double weight,
              const Material* medium);
  Color shade(const Vec3& o, const Vec3& d, const SurfaceHit& hit, int depth, double weight,
              const Material* medium);
};

// ---- The user geometry: spheres and cones, exact ----

void quadric_bounds(const RTCBoundsFunctionArguments* args) {
  const Peer& peer = *static_cast<const Peer*>(args->geometryUserPtr);
  const Aabb& b = peer.ps.prims.bounds[peer.quadric_prim[args->primID]];
  // Rounded outwards to float.
  args->bounds_o->lower_x = std::nextafter(static_cast<float>(b.lo.x), -INFINITY);
  args->bounds_o->lower_y = std::nextafter(static_cast<float>(b.lo.y), -INFINITY);
  args->bounds_o->lower_z = std::nextafter(static_cast<float>(b.lo.z), -INFINITY);
  args->bounds_o->upper_x = std::nextafter(static_cast<float>(b.hi.x), INFINITY);
  args->bounds_o->upper_y = std::nextafter(static_cast<float>(b.hi.y), INFINITY);
  args->bounds_o->upper_z = std::nextafter(static_cast<float>(b.hi.z), INFINITY);
}

void quadric_intersect(const RTCIntersectFunctionNArguments* args) {
  if (!args->valid[0]) return;
  auto* ctx = reinterpret_cast<RayContext*>(args->context);
  auto* rh = reinterpret_cast<RTCRayHit*>(args->rayhit);
  const Peer& peer = *ctx->peer;
  const PrimRef& ref = peer.ps.prims.prims[peer.quadric_prim[args->primID]];
  const double tmax = std::min(ctx->quadric_t, static_cast<double>(rh->ray.tfar));
  double t = kInf;
  if (ref.kind == PrimKind::kSphere) {
    t = sphere_t(peer.ps.prims.spheres[ref.index].s, ctx->o, ctx->d, ctx->tmin, tmax);
  } else {
    double ts[2];
    if (cone_ts(peer.ps.prims.cones[ref.index], ctx->o, ctx->d, ctx->tmin, tmax, ts) > 0) t = ts[0];
  }
  if (!(t < tmax)) return;
  ctx->quadric_t = t;
  ctx->quadric_prim = args->primID;
  rh->ray.tfar = static_cast<float>(t);
  rh->hit.geomID = args->geomID;
  rh->hit.primID = args->primID;
  rh->hit.u = rh->hit.v = 0.0f;
  rh->hit.instID[0] = args->context->instID[0];
}

void quadric_occluded(const RTCOccludedFunctionNArguments* args) {
  if (!args->valid[0]) return;
  auto* ctx = reinterpret_cast<RayContext*>(args->context);
  auto* ray = reinterpret_cast<RTCRay*>(args->ray);
  const Peer& peer = *ctx->peer;
  const int prim = peer.quadric_prim[args->primID];
  const PrimRef& ref = peer.ps.prims.prims[prim];
  double ts[2];
  int n = 0;
  if (ref.kind == PrimKind::kSphere) {
    const Sphere& s = peer.ps.prims.spheres[ref.index].s;
    const Vec3 oc = ctx->o - s.center;
    double t0, t1;
    if (solve_quadratic(glm::dot(ctx->d, ctx->d), 2.0 * glm::dot(oc, ctx->d),
                        glm::dot(oc, oc) - s.radius * s.radius, &t0, &t1)) {
      for (double t : {t0, t1}) {
        if (t > ctx->tmin && t < ctx->tmax) ts[n++] = t;
      }
    }
  } else {
    n = cone_ts(peer.ps.prims.cones[ref.index], ctx->o, ctx->d, ctx->tmin, ctx->tmax, ts);
  }
  if (n == 0) return;
  if (!peer.prim_clear[prim]) {
    ray->tfar = -INFINITY;  // eq. (2): an opaque occluder stops everything
    return;
  }
  for (int i = 0; i < n; ++i) {
    const Vec3 x = ctx->o + ts[i] * ctx->d;
    const Vec3 normal = ref.kind == PrimKind::kSphere
                            ? (x - peer.ps.prims.spheres[ref.index].s.center) /
                                  peer.ps.prims.spheres[ref.index].s.radius
                            : cone_normal(peer.ps.prims.cones[ref.index], x);
    ctx->crossings->push_back(Crossing{ts[i], normal, ref.object});
  }
}

// Shadow rays through transparent triangles: the crossing is kept for
// eq. (3) and the hit refused, so the search goes on. A polygon cut into
// triangles counts once.
void clear_tri_filter(const RTCFilterFunctionNArguments* args) {
  if (!args->valid[0]) return;
  auto* ctx = reinterpret_cast<RayContext*>(args->context);
  const Peer& peer = *ctx->peer;
  const unsigned tri = RTCHitN_primID(args->hit, args->N, 0);
  const int prim = peer.tri_prim[kClearTris][tri];
  args->valid[0] = 0;
  if (std::find(ctx->crossed->begin(), ctx->crossed->end(), prim) != ctx->crossed->end()) return;
  ctx->crossed->push_back(prim);
  Crossing c =
      peer.flat_crossing(prim, ctx->o, ctx->d, RTCRayN_tfar(args->ray, args->N, 0),
                         RTCHitN_u(args->hit, args->N, 0), RTCHitN_v(args->hit, args->N, 0));
  ctx->crossings->push_back(c);
}

Status Peer::build(bool robust) {
  device = rtcNewDevice("threads=1,set_affinity=0");
  if (!device) return Internal("rtcNewDevice failed");
  scene = rtcNewScene(device);
  if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  const PrimitiveSet& set = ps.prims;
  prim_clear.resize(set.prims.size());
  std::vector<float> verts[2];
  std::vector<unsigned> index[2];
  auto add_tri = [&](int kind, int prim, const Vec3& a, const Vec3& b, const Vec3& c) {
    const unsigned first = static_cast<unsigned>(verts[kind].size() / 3);
    for (const Vec3* p : {&a, &b, &c}) {
      verts[kind].push_back(static_cast<float>(p->x));
      verts[kind].push_back(static_cast<float>(p->y));
      verts[kind].push_back(static_cast<float>(p->z));
    }
    index[kind].insert(index[kind].end(), {first, first + 1, first + 2});
    tri_prim[kind].push_back(prim);
  };
  for (int i = 0; i < static_cast<int>(set.prims.size()); ++i) {
    const PrimRef& ref = set.prims[i];
    prim_clear[i] = material_of(i).t > 0.0;
    any_clear = any_clear || prim_clear[i];
    const int kind = prim_clear[i] ? kClearTris : kOpaqueTris;
    switch (ref.kind) {
      case PrimKind::kTriangle: {
        const TrianglePrim& t = set.triangles[ref.index];
        add_tri(kind, i, t.p0, t.p0 + t.e1, t.p0 + t.e2);
        break;
      }
      case PrimKind::kPolygon: {
        const PolygonPrim& p = set.polygons[ref.index];
        const std::vector<Vec3> outline = polygon_outline(p);
        for (const auto& [a, b, c] : triangulate(p.pts))
          add_tri(kind, i, outline[a], outline[b], outline[c]);
        break;
      }
      case PrimKind::kSphere:
        if (!set.spheres[ref.index].frame.identity) return InvalidArgument("transformed sphere");
        quadric_prim.push_back(i);
        break;
      case PrimKind::kCone:
        if (!set.cones[ref.index].frame.identity) return InvalidArgument("transformed cone");
        if (set.cones[ref.index].c.capped) return InvalidArgument("capped cone (not in NFF)");
        quadric_prim.push_back(i);
        break;
      default:
        return InvalidArgument("only triangles, polygons, spheres and open cones (NFF)");
    }
  }
  // Geometry ids 0, 1, 2 in this order, each attached even when empty.
  for (int kind : {kOpaqueTris, kClearTris}) {
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    const size_t nv = verts[kind].size() / 3, nt = index[kind].size() / 3;
    if (nt > 0) {
      auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
      std::copy(verts[kind].begin(), verts[kind].end(), vb);
      auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
          g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), nt));
      std::copy(index[kind].begin(), index[kind].end(), ib);
    }
    if (kind == kClearTris) rtcSetGeometryOccludedFilterFunction(g, clear_tri_filter);
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(scene, g, kind);
    rtcReleaseGeometry(g);
  }
  RTCGeometry q = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(q, static_cast<unsigned>(quadric_prim.size()));
  rtcSetGeometryUserData(q, this);
  rtcSetGeometryBoundsFunction(q, quadric_bounds, this);
  rtcSetGeometryIntersectFunction(q, quadric_intersect);
  rtcSetGeometryOccludedFunction(q, quadric_occluded);
  rtcCommitGeometry(q);
  rtcAttachGeometryByID(scene, q, kQuadrics);
  rtcReleaseGeometry(q);
  rtcCommitScene(scene);
  if (rtcGetDeviceError(device) != RTC_ERROR_NONE) return Internal("Embree scene build failed");
  return Status();
}

std::optional<SurfaceHit> Peer::nearest(const Vec3& o, const Vec3& d, double tmin) {
  RayContext ctx;
  rtcInitIntersectContext(&ctx.base);
  ctx.peer = this;
  ctx.o = o, ctx.d = d, ctx.tmin = tmin;
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(o.x), rh.ray.org_y = static_cast<float>(o.y);
  rh.ray.org_z = static_cast<float>(o.z);
  rh.ray.dir_x = static_cast<float>(d.x), rh.ray.dir_y = static_cast<float>(d.y);
  rh.ray.dir_z = static_cast<float>(d.z);
  rh.ray.tnear = static_cast<float>(tmin);
  rh.ray.tfar = INFINITY;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &ctx.base, &rh);
  const unsigned g = rh.hit.geomID;
  if (g == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  SurfaceHit hit;
  if (g == kQuadrics) {
    hit.prim = quadric_prim[rh.hit.primID];
    hit.t = ctx.quadric_t;
    const PrimRef& ref = ps.prims.prims[hit.prim];
    const Vec3 x = o + hit.t * d;
    hit.crossing.t = hit.t;
    hit.crossing.leaf = ref.object;
    hit.crossing.normal =
        ref.kind == PrimKind::kSphere
            ? (x - ps.prims.spheres[ref.index].s.center) / ps.prims.spheres[ref.index].s.radius
            : cone_normal(ps.prims.cones[ref.index], x);
    return hit;
  }
  hit.prim = tri_prim[g][rh.hit.primID];
  hit.crossing = flat_crossing(hit.prim, o, d, rh.ray.tfar, rh.hit.u, rh.hit.v);
  hit.t = hit.crossing.t;
  return hit;
}

Color Peer::transmittance(const Vec3& p, const Vec3& ng, int light) {
  const Vec3 lp = ps.scene.lights[light].position;
  const Vec3 origin = p + (glm::dot(lp - p, ng) >= 0 ? ps.eps : -ps.eps) * ng;
  ++stats.rays_shadow;
  const Ray seg{origin, lp - origin};  // t in (0, 1) spans the segment
  thread_local std::vector<Crossing> crossings;
  thread_local std::vector<int> crossed;
  crossings.clear();
  crossed.clear();
  RayContext ctx;
  rtcInitIntersectContext(&ctx.base);
  ctx.peer = this;
  ctx.o = seg.origin, ctx.d = seg.dir, ctx.tmin = 0.0, ctx.tmax = 1.0;
  ctx.crossings = &crossings;
  ctx.crossed = &crossed;
  RTCRay ray{};
  ray.org_x = static_cast<float>(origin.x), ray.org_y = static_cast<float>(origin.y);
  ray.org_z = static_cast<float>(origin.z);
  ray.dir_x = static_cast<float>(seg.dir.x), ray.dir_y = static_cast<float>(seg.dir.y);
  ray.dir_z = static_cast<float>(seg.dir.z);
  ray.tnear = 0.0f;
  ray.tfar = 1.0f;
  ray.mask = ~0u;
  rtcOccluded1(scene, &ctx.base, &ray);
  if (ray.tfar < 0.0f) return Color(0.0);
  if (crossings.empty()) return Color(1.0);
  // Only the crossings inside the segment, in double.
  std::erase_if(crossings, [](const Crossing& c) { return !(c.t > 0.0 && c.t < 1.0); });
  return segment_transmittance(ps.scene, seg, crossings);
}

Color Peer::trace(const Vec3& o, const Vec3& d, double tmin, int depth, double weight,
                  const Material* medium) {
  const auto hit = nearest(o, d, tmin);
  if (!hit) return ps.scene.background;
  return shade(o, d, *hit, depth, weight, medium);
}

// Tracer::shade's shading (SHADING.md "Materials"), with the peer's rays.
Color Peer::shade(const Vec3& o, const Vec3& d, const SurfaceHit& hit, int depth, double weight,
                  const Material* medium) {
  const Scene& sc = ps.scene;
  const Crossing& c = hit.crossing;
  const Material& m = sc.materials[sc.objects[c.leaf].material];
  Color atten(1.0);
  if (medium && medium->absorption != Color(0.0)) atten = beer(medium->absorption, hit.t);
  const double w = weight * max_component(atten);

  const Vec3 p = o + hit.t * d;
  const Vec3 ng = c.normal;
  const bool entering = glm::dot(d, ng) < 0;
  Vec3 n = shading_normal(ps.prims, ps.prims.prims[hit.prim], c);
  if (glm::dot(n, d) > 0) n = -n;
  const Vec3 v = -d;

  Color result = ps.ambient * m.kd * m.color;
  for (int j = 0; j < static_cast<int>(sc.lights.size()); ++j) {
    const Vec3 l = glm::normalize(sc.lights[j].position - p);
    const double ndl = glm::dot(n, l);
    if (ndl <= 0) continue;
    if (m.kd == 0 && m.ks == 0) continue;
    const Color tp = transmittance(p, ng, j);
    if (tp == Color(0.0)) continue;
    const Vec3 r = 2.0 * ndl * n - l;
    const double spec = m.ks > 0 ? m.ks * std::pow(std::max(0.0, glm::dot(r, v)), m.shine) : 0.0;
    result += ps.emission[j] * tp * (m.kd * ndl * m.color + Color(spec));
  }

  if (depth < kMaxDepth) {
    auto spawn = [&](const Vec3& dir, double coef, const Material* med) {
      const Vec3 origin = p + (glm::dot(dir, ng) >= 0 ? ps.eps : -ps.eps) * ng;
      return trace(origin, dir, 0.0, depth + 1, w * coef, med);
    };
    if (m.ks > 0 && w * m.ks >= kMinWeight) {
      ++stats.rays_reflected;
      result += m.ks * spawn(reflect(d, n), m.ks, medium);
    }
    if (m.t > 0 && w * m.t >= kMinWeight) {
      const double eta = entering ? 1.0 / m.ior : m.ior;
      if (const auto dir = refract(d, n, eta)) {
        ++stats.rays_refracted;
        result += m.t * spawn(*dir, m.t, entering ? &m : nullptr);
      } else {
        ++stats.rays_reflected;
        result += m.t * spawn(reflect(d, n), m.t, medium);
      }
    }
  }
  return atten * result;
}

int run(const std::string& path, const std::string& size, const std::string& output, bool robust) {
  Result<Scene> scene = load_scene(path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  if (!size.empty()) {
    int w = 0, h = 0;
    if (std::sscanf(size.c_str(), "%dx%d", &w, &h) != 2 || w < 1 || h < 1) {
      std::fprintf(stderr, "--size: expected WIDTHxHEIGHT, got '%s'\n", size.c_str());
      return 2;
    }
    scene->camera.width = w;
    scene->camera.height = h;
  }
  const auto wall = [] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  };
  const double w0 = wall();
  RenderParams params;
  params.method = Method::kRaytrace;
  params.boxes = Boxes::kNone;  // Locus's own hierarchy is not used here
  params.threads = 1;
  auto ps = prepare_scene(*scene, params);
  if (!ps.ok()) {
    std::fprintf(stderr, "%s\n", ps.status().message().c_str());
    return 1;
  }
  Peer peer(**ps);
  if (Status s = peer.build(robust); !s.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), s.message().c_str());
    return 1;
  }
  const double build_wall = wall() - w0;

  const CameraFrame& cam = (*ps)->camera;
  Image image(cam.width, cam.height);
  const Band band{0, cam.height};
  const double c0 = process_cpu_seconds(), t0 = thread_cpu_seconds(), r0 = wall();
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      ++peer.stats.rays_eye;
      const Color c =
          peer.trace(cam.from, cam.direction(x + 0.5, y + 0.5), cam.hither, 1, 1.0, nullptr);
      store_pixel(image, band, x, y, c);
    }
  }
  const double render_cpu = process_cpu_seconds() - c0, render_thread = thread_cpu_seconds() - t0;
  const double render_wall = wall() - r0;
  if (!output.empty()) {
    if (Status s = write_image(output, image); !s.ok()) {
      std::fprintf(stderr, "%s\n", s.message().c_str());
      return 1;
    }
  }
  const Stats& st = peer.stats;
  std::printf(
      "{\n  \"seconds\": {\"build\": %.9g, \"render\": %.9g, \"render_cpu\": %.9g, "
      "\"render_cpu_thread\": %.9g},\n"
      "  \"rays\": {\"eye\": %llu, \"reflected\": %llu, \"refracted\": %llu, \"shadow\": %llu},\n"
      "  \"embree\": {\"triangles\": %zu, \"clear_triangles\": %zu, \"quadrics\": %zu, "
      "\"robust\": %s, \"version\": \"%d.%d.%d\"}\n}\n",
      build_wall, render_wall, render_cpu, render_thread,
      static_cast<unsigned long long>(st.rays_eye),
      static_cast<unsigned long long>(st.rays_reflected),
      static_cast<unsigned long long>(st.rays_refracted),
      static_cast<unsigned long long>(st.rays_shadow), peer.tri_prim[kOpaqueTris].size(),
      peer.tri_prim[kClearTris].size(), peer.quadric_prim.size(), robust ? "true" : "false",
      RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH);
  return 0;
}

}  // namespace
}  // namespace locus

int main(int argc, char** argv) {
  CLI::App app{
      "A minimal Whitted ray tracer on Embree 3: the peer of "
      "`locus render --method raytrace --spp 1` (bench/peers/kernel.py)"};
  std::string scene, size, output;
  bool robust = false;
  app.add_option("scene", scene, "Scene file (.nff or .json)")->required();
  app.add_option("--size", size, "Override the resolution, WIDTHxHEIGHT");
  app.add_option("-o,--output", output, "Write the image (.exr, .png, .tif)");
  app.add_flag("--robust", robust, "Embree's RTC_SCENE_FLAG_ROBUST (slower, watertight traversal)");
  CLI11_PARSE(app, argc, argv);
  return locus::run(scene, size, output, robust);
}
