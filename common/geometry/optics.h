// Reflection, refraction and Fresnel reflectance (SHADING.md; paper eq. (3)).
#pragma once

#include <cmath>
#include <optional>

#include "common/base/math.h"

namespace locus {

// Mirror direction of d about unit normal n.
inline Vec3 reflect(const Vec3& d, const Vec3& n) { return d - 2.0 * glm::dot(d, n) * n; }

// Snell refraction of unit d through unit normal n facing the incoming ray
// (dot(d, n) < 0), eta = n1 / n2. Empty under total internal reflection.
inline std::optional<Vec3> refract(const Vec3& d, const Vec3& n, double eta) {
  const double cos_i = -glm::dot(d, n);
  const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
  if (sin2_t > 1.0) return std::nullopt;
  const double cos_t = std::sqrt(1.0 - sin2_t);
  return glm::normalize(eta * d + (eta * cos_i - cos_t) * n);
}

// Unpolarised Fresnel reflectance for light going from index n1 to n2 at
// incidence cosine cos_i; 1 beyond the critical angle (paper §4.2: the dark
// cores in the shadow of a glass cylinder).
inline double fresnel(double cos_i, double n1, double n2) {
  cos_i = std::fabs(cos_i);
  if (cos_i > 1.0) cos_i = 1.0;
  const double eta = n1 / n2;
  const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
  if (sin2_t >= 1.0) return 1.0;
  const double cos_t = std::sqrt(1.0 - sin2_t);
  const double rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
  const double rp = (n1 * cos_t - n2 * cos_i) / (n1 * cos_t + n2 * cos_i);
  return 0.5 * (rs * rs + rp * rp);
}

}  // namespace locus
