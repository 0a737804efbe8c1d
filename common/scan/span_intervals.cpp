// Where one span meets one occluder: the rectangle test of groups of lines
// and the exact intervals of opaque spheres and cones (span_intervals.h).
#include "common/scan/span_intervals.h"

#include <algorithm>
#include <cmath>

namespace locus {

// Whether volume v may hold some O(a, b) of the rectangle. A plane
// m . x <= h + slack at O, multiplied by n . D (of sign sigma wherever the
// face is in front of the eye), reads K0 + Ka a + Kb b <= 0: a half-plane
// of the image. The rectangle is clipped by each (Sutherland-Hodgman); the
// volume misses it when nothing is left. Conservative: a vertex beyond a
// plane by no more than rounding is kept, so no line of the group loses an
// interval its own walk would find.
bool meets_rect(const VolumeSet& set, int v, const GroupRect& r, double slack) {
  const ShadowVolume& vol = set.volumes[v];
  if (vol.kind != VolumeKind::kConvex) return true;
  constexpr int kMax = 40;
  double pa[2][kMax], pb[2][kMax];
  int n = 4;
  pa[0][0] = r.a0, pb[0][0] = r.b0;
  pa[0][1] = r.a1, pb[0][1] = r.b0;
  pa[0][2] = r.a1, pb[0][2] = r.b1;
  pa[0][3] = r.a0, pb[0][3] = r.b1;
  const double amax = std::max(std::abs(r.a0), std::abs(r.a1));
  const double bmax = std::max(std::abs(r.b0), std::abs(r.b1));
  // Plane i as K0 + Ka a + Kb b <= tol over the rectangle.
  struct Line {
    double k0, ka, kb, tol;
  };
  auto line_of = [&](int i) {
    const VolumeSet::CameraDots& k = set.cam[i];
    const double c0 = k.me + glm::dot(set.planes[i].m, r.delta) - slack;
    Line q;
    q.k0 = r.sigma * (c0 * r.nw + r.num * k.mw);
    q.ka = r.sigma * (c0 * r.nu + r.num * k.mu);
    q.kb = r.sigma * (c0 * r.nv + r.num * k.mv);
    q.tol = 1e-9 * (std::abs(q.k0) + std::abs(q.ka) * amax + std::abs(q.kb) * bmax);
    return q;
  };
  // Most volumes that miss lie wholly beyond one of their planes: the four
  // corners tell, with no clipping (a linear function's least value on a
  // rectangle is at a corner).
  for (int i = vol.first; i < vol.first + vol.count; ++i) {
    const Line q = line_of(i);
    if (q.k0 + std::min(q.ka * r.a0, q.ka * r.a1) + std::min(q.kb * r.b0, q.kb * r.b1) - q.tol >
        0) {
      return false;
    }
  }
  int cur = 0;
  for (int i = vol.first; i < vol.first + vol.count; ++i) {
    if (n + 1 > kMax) return true;
    const Line q = line_of(i);
    const double k0 = q.k0, ka = q.ka, kb = q.kb, tol = q.tol;
    const double* xa = pa[cur];
    const double* xb = pb[cur];
    double* ya = pa[1 - cur];
    double* yb = pb[1 - cur];
    int m = 0;
    double vp = k0 + ka * xa[n - 1] + kb * xb[n - 1] - tol;
    for (int q = 0, p = n - 1; q < n; p = q++) {
      const double vq = k0 + ka * xa[q] + kb * xb[q] - tol;
      if ((vp <= 0) != (vq <= 0)) {
        const double t = vp / (vp - vq);
        ya[m] = xa[p] + t * (xa[q] - xa[p]);
        yb[m] = xb[p] + t * (xb[q] - xb[p]);
        ++m;
      }
      if (vq <= 0) {
        ya[m] = xa[q];
        yb[m] = xb[q];
        ++m;
      }
      vp = vq;
    }
    if (m == 0) return false;
    n = m;
    cur = 1 - cur;
  }
  return true;
}

// Exact shadow intervals of opaque spheres and cones (docs/shadow-volumes.md
// "Exact intervals of curved occluders"). The lines through the light L
// and the span's shadow-ray origins O(a) form a pencil (common/geometry/pencil.h),
// with directions (nw + a nu) (O(a) - L) = p0 + a p1, linear in a. The
// line at a meets the body's quadric where e(a) >= 0: for a sphere that is
// the shadow. For a cone or cylinder, whether the line meets the body
// between its rims changes only at those ends or where it passes through a
// point of a rim circle; between two such events, one line test decides.
// Either way the result is the shadow ray's (eqs. (2), (3)) when the body
// lies strictly between the origins and the light: a line that meets it
// then does so inside the segment from O(a) to L.
bool between_origins_and_light(const PrimitiveSet& prims, int prim, const Vec3& n, double offset,
                               double sigma, double h0, double hl, double margin) {
  if (!plain_quadric(prims, prim)) return false;
  const PrimRef& ref = prims.prims[prim];
  double lo, hi;
  if (ref.kind == PrimKind::kSphere) {
    const SpherePrim& s = prims.spheres[ref.index];
    const double h = sigma * (glm::dot(n, s.s.center) - offset);
    lo = h - s.s.radius;
    hi = h + s.s.radius;
  } else {
    const ConePrim& c = prims.cones[ref.index];
    // A rim circle of radius r reaches r sqrt(1 - (n . axis)^2) off its centre's height.
    const double na = glm::dot(n, c.axis.a);
    const double spread = std::sqrt(std::max(0.0, 1.0 - na * na));
    const double hb = sigma * (glm::dot(n, c.c.base) - offset);
    const double ha = hb + sigma * na * c.axis.h;
    const double eb = c.c.base_radius * spread, ea = c.c.apex_radius * spread;
    lo = std::min(hb - eb, ha - ea);
    hi = std::max(hb + eb, ha + ea);
  }
  return lo > h0 + margin && hi < hl - margin;
}

bool exact_intervals(const PrimitiveSet& prims, int prim, const Pencil& pen, double a_first,
                     double a_last, std::vector<double>& events, Stats& stats,
                     std::vector<SpanInterval>& out) {
  events.clear();
  double e[3];
  if (!pencil_events(prims, prim, pen, e, events)) return false;
  // The line cut at the events inside it; each part decided at its
  // middle: the pencil's line there meets the quadric (e >= 0) and, for
  // a cone, the surface between its rims. The line meets the body only
  // between the origin and the light (between_origins_and_light).
  events.erase(std::remove_if(events.begin(), events.end(),
                              [&](double a) { return !(a > a_first && a < a_last); }),
               events.end());
  std::sort(events.begin(), events.end());
  events.push_back(a_last);
  const PrimRef& ref = prims.prims[prim];
  bool open = false;
  double start = 0, x = a_first;
  for (const double y : events) {
    if (!(y > x)) continue;
    const double a = 0.5 * (x + y);
    bool in = (e[0] * a + e[1]) * a + e[2] >= 0;
    if (in && ref.kind == PrimKind::kCone) {
      const ConePrim& cone = prims.cones[ref.index];
      ++stats.tests_ray_object;
      in = intersect_cone(cone.c, cone.axis, Ray{pen.point, pen.p0 + a * pen.p1}, -kInf, kInf,
                          nullptr) > 0;
    }
    // Shadowed parts are merged into intervals.
    if (in && !open) start = x;
    if (!in && open) out.push_back(SpanInterval{prim, true, start, x, false});
    open = in;
    x = y;
  }
  if (open) out.push_back(SpanInterval{prim, true, start, a_last, false});
  return true;
}

}  // namespace locus
