// Pencils of lines and the events along them (common/geometry/pencil.h).
#include "common/geometry/pencil.h"

#include <cmath>

namespace locus {
namespace {

// e(a)'s coefficients (pencil_events). The line P + t (p0 + a p1) meets
// the quadric where A t^2 + 2 B t + C = 0 (the forms of intersect_sphere
// and intersect_cone), with A quadratic in a, B linear and C constant:
// e = B^2 - A C.
void pencil_quadric(const PrimitiveSet& prims, int prim, const Pencil& pen, double e[3]) {
  double a0, a1, a2, b0, b1, cq;
  const PrimRef& ref = prims.prims[prim];
  if (ref.kind == PrimKind::kSphere) {
    const Sphere& s = prims.spheres[ref.index].s;
    const Vec3 co = pen.point - s.center;
    a0 = glm::dot(pen.p0, pen.p0);
    a1 = 2.0 * glm::dot(pen.p0, pen.p1);
    a2 = glm::dot(pen.p1, pen.p1);
    b0 = glm::dot(co, pen.p0);
    b1 = glm::dot(co, pen.p1);
    cq = glm::dot(co, co) - s.radius * s.radius;
  } else {
    const ConePrim& c = prims.cones[ref.index];
    const Vec3& ax = c.axis.a;
    const double k = c.axis.k;
    const Vec3 co = pen.point - c.c.base;
    const double ca = glm::dot(co, ax);
    const Vec3 cp = co - ca * ax;
    const double rc = c.c.base_radius + k * ca;
    const double d0 = glm::dot(pen.p0, ax), d1 = glm::dot(pen.p1, ax);
    const Vec3 q0 = pen.p0 - d0 * ax, q1 = pen.p1 - d1 * ax;
    a0 = glm::dot(q0, q0) - k * k * d0 * d0;
    a1 = 2.0 * (glm::dot(q0, q1) - k * k * d0 * d1);
    a2 = glm::dot(q1, q1) - k * k * d1 * d1;
    b0 = glm::dot(cp, q0) - k * rc * d0;
    b1 = glm::dot(cp, q1) - k * rc * d1;
    cq = glm::dot(cp, cp) - rc * rc;
  }
  e[0] = b1 * b1 - a2 * cq;
  e[1] = 2.0 * b0 * b1 - a1 * cq;
  e[2] = b0 * b0 - a0 * cq;
}

// The a where the pencil's line passes through a point of one of cone c's
// rim circles, appended to `ev`; false if the pencil's plane is parallel to
// the rims' planes.
bool rim_events(const ConePrim& c, const Pencil& pen, std::vector<double>& ev) {
  const Vec3& ax = c.axis.a;
  // The pencil's plane (normal m) cuts a rim circle (centre r, radius
  // rho, in the plane normal to ax) in at most two points, on the chord
  // along e = m x ax.
  const Vec3 m = glm::cross(pen.p0, pen.p1);
  const Vec3 mp = m - glm::dot(m, ax) * ax;
  const double mp2 = glm::dot(mp, mp);  // = |e|^2
  if (!(mp2 > 1e-24 * glm::dot(m, m))) return false;
  const Vec3 e = glm::cross(m, ax);
  for (int end = 0; end < 2; ++end) {
    const Vec3 r = end == 0 ? c.c.base : c.c.base + c.axis.h * ax;
    const double rho = end == 0 ? c.c.base_radius : c.c.apex_radius;
    const double g = glm::dot(m, r - pen.point);
    const double d2 = g * g / mp2;  // squared distance from r to the chord
    if (d2 > rho * rho) continue;
    const Vec3 x0 = r - (g / mp2) * mp;
    const double half = std::sqrt((rho * rho - d2) / mp2);
    for (const double sgn : {-1.0, 1.0}) {
      // The a whose direction p0 + a p1 is parallel to x - L.
      const Vec3 x = x0 + sgn * half * e - pen.point;
      const Vec3 c0 = glm::cross(x, pen.p0), c1 = glm::cross(x, pen.p1);
      const double den = glm::dot(c1, c1);
      if (den > 0) ev.push_back(-glm::dot(c0, c1) / den);
    }
  }
  return true;
}

}  // namespace

bool pencil_events(const PrimitiveSet& prims, int prim, const Pencil& pen, double e[3],
                   std::vector<double>& ev) {
  const size_t before = ev.size();
  pencil_quadric(prims, prim, pen, e);
  double t0, t1;
  if (solve_quadratic(e[0], e[1], e[2], &t0, &t1)) {
    ev.push_back(t0);
    if (t1 != t0) ev.push_back(t1);
  }
  const PrimRef& ref = prims.prims[prim];
  if (ref.kind == PrimKind::kCone && !rim_events(prims.cones[ref.index], pen, ev)) {
    ev.resize(before);
    return false;
  }
  return true;
}

}  // namespace locus
