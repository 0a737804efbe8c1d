// Shadows at single points (paper §4.1; docs/shadow-volumes.md "Shadows at
// other points"): the exact test of one occluder, and the search of the
// shadow volumes that common/prepare/shadow_volume.h builds, for points
// reached by secondary rays.
#pragma once

#include <vector>

#include "common/base/math.h"
#include "common/base/params.h"
#include "common/geometry/geometry.h"
#include "common/prepare/prepared.h"

namespace locus {

// t_pj (eqs. (2), (3)) of light `light` at the shadow-ray origin `origin`
// of a point on primitive `receiver` (-1: unknown), found by walking the
// hierarchy with the boxes' shadow volumes, narrowing by the receiver's
// candidate list and testing containment (paper §4.1). Equals
// Tracer::transmittance with shadow rays. `last_occluder` (may be null)
// names an opaque occluder to test first, and is updated (a shadow cache).
Color volume_transmittance(const PreparedScene& ps, const Vec3& origin, int light, int receiver,
                           Stats& stats, int* last_occluder = nullptr);

// Whether the solid of sphere or cone `prim` (a frustum's is convex, caps
// or not) lies wholly behind a plane that has the shadow-ray origin o and
// the light l strictly in front, so that the segment cannot meet its
// surface. A convex receiver's own surface thus never shadows a point that
// faces the light from outside, where most of its samples lie.
bool beyond_support(const PrimitiveSet& prims, int prim, const Vec3& o, const Vec3& l);

// The exact segment test of one occluder (a curved body, CSG, a
// transparent or unformed volume) along `seg` (t in (0, 1)): its crossings
// are appended; true if one of them is opaque (eq. (2): t_pj = 0).
bool exact_test(const PreparedScene& ps, int prim, const Ray& seg, std::vector<Crossing>& crossings,
                Stats& stats);

}  // namespace locus
