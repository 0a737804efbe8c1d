// Seeded random directions for the geometry tests.
#pragma once

#include <random>

#include "common/base/math.h"

namespace locus {

// A direction uniform on the unit sphere (a normal vector normalised).
inline Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  for (;;) {
    const Vec3 v(g(rng), g(rng), g(rng));
    const double l = glm::length(v);
    if (l > 1e-6) return v / l;
  }
}

}  // namespace locus
