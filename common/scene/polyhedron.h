// Builders for convex polyhedra (scene.h Polyhedron): boxes, regular prisms
// and the convex hull of a point set.
#pragma once

#include <optional>
#include <vector>

#include "common/scene/scene.h"

namespace locus {

// Limits the scene loaders enforce (docs/scene-format.md). make_hull costs
// O(n^2) in the worst case and the renderer tests a ray against every face
// of a polyhedron, so large point sets belong in a Mesh instead.
inline constexpr int kMaxHullVertices = 1024;
inline constexpr int kMaxPrismSides = 1024;

Polyhedron make_box(const Vec3& lo, const Vec3& hi);
// Right prism over a regular n-gon of circumradius r, from base to apex.
Polyhedron make_prism(int sides, double radius, const Vec3& base, const Vec3& apex,
                      double twist_degrees = 0.0);
// Convex hull; nullopt if the points do not span a volume. Coplanar hull
// triangles are merged into polygon faces; points inside the hull or on its
// faces or edges are dropped, so every vertex is a corner.
std::optional<Polyhedron> make_hull(const std::vector<Vec3>& points);

}  // namespace locus
