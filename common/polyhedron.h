// Builders for convex polyhedra (scene.h Polyhedron): boxes, regular prisms
// and the convex hull of a point set.
#pragma once

#include <optional>
#include <vector>

#include "common/scene.h"

namespace locus {

Polyhedron make_box(const Vec3& lo, const Vec3& hi);
// Right prism over a regular n-gon of circumradius r, from base to apex.
Polyhedron make_prism(int sides, double radius, const Vec3& base, const Vec3& apex,
                      double twist_degrees = 0.0);
// Convex hull; nullopt if the points do not span a volume.
std::optional<Polyhedron> make_hull(const std::vector<Vec3>& points);

}  // namespace locus
