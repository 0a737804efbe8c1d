// Vector types and small numeric helpers shared by the renderer.
#pragma once

#include <cmath>
#include <glm/glm.hpp>
#include <limits>
#include <utility>
#include <vector>

namespace locus {

inline constexpr double kInf = std::numeric_limits<double>::infinity();
// Relative depth difference below which two surfaces are coincident, in the
// ray tracer's nearest() and in the scanline pass alike (docs/renderer.md).
inline constexpr double kTieRel = 1e-9;

using Vec3 = glm::dvec3;
using Vec2 = glm::dvec2;
using Mat4 = glm::dmat4;
using Color = glm::dvec3;

inline double max_component(const Vec3& v) { return glm::max(v.x, glm::max(v.y, v.z)); }
inline double min_component(const Vec3& v) { return glm::min(v.x, glm::min(v.y, v.z)); }

inline bool is_finite(double x) { return x - x == 0.0; }
inline bool is_finite(const Vec3& v) { return is_finite(v.x) && is_finite(v.y) && is_finite(v.z); }

// floor(x) and ceil(x) as an int clamped to [lo, hi] (lo <= hi), clamped
// before the conversion: a projected coordinate can lie far beyond int's
// range (a vertex just in front of the eye, a huge scene), and NaN gives lo.
inline int clamped_floor(double x, int lo, int hi) {
  const double f = std::floor(x);
  return !(f > lo) ? lo : (f >= hi ? hi : static_cast<int>(f));
}
inline int clamped_ceil(double x, int lo, int hi) {
  const double c = std::ceil(x);
  return !(c > lo) ? lo : (c >= hi ? hi : static_cast<int>(c));
}

// Apply an affine transform to a point / a direction / a normal.
inline Vec3 transform_point(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }
inline Vec3 transform_vector(const Mat4& m, const Vec3& v) { return Vec3(m * glm::dvec4(v, 0.0)); }

// Roots of a t^2 + b t + c = 0 in increasing order, computed without
// catastrophic cancellation. Returns the number of real roots (0 or 2; a
// linear equation's one root is returned twice).
inline int solve_quadratic(double a, double b, double c, double* t0, double* t1) {
  if (a == 0.0) {
    if (b == 0.0) return 0;
    *t0 = *t1 = -c / b;
    return 2;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return 0;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  double r0 = q / a;
  double r1 = q != 0.0 ? c / q : r0;
  if (r0 > r1) std::swap(r0, r1);
  *t0 = r0;
  *t1 = r1;
  return 2;
}

// An arbitrary unit vector perpendicular to unit vector n.
inline Vec3 any_perpendicular(const Vec3& n) {
  const Vec3 a = glm::abs(n.x) < 0.6 ? Vec3(1, 0, 0) : (glm::abs(n.y) < 0.6 ? Vec3(0, 1, 0) : Vec3(0, 0, 1));
  return glm::normalize(glm::cross(n, a));
}

// Newell's method: twice the area vector of a polygon, exact for planar
// polygons of any shape (convex or not) and a best fit for slightly bent
// ones. Unnormalised: its length says whether the polygon has an area.
inline Vec3 newell_vector(const std::vector<Vec3>& v) {
  Vec3 n(0.0);
  for (size_t i = 0; i < v.size(); ++i) {
    const Vec3& p = v[i];
    const Vec3& q = v[(i + 1) % v.size()];
    n.x += (p.y - q.y) * (p.z + q.z);
    n.y += (p.z - q.z) * (p.x + q.x);
    n.z += (p.x - q.x) * (p.y + q.y);
  }
  return n;
}

}  // namespace locus
