// A pencil of lines: the lines through one point P (a light, or the eye)
// and the points of another line, whose directions are p0 + a p1 for a
// real parameter a (an image coordinate). Along a pencil, whether a line
// meets a sphere or cone changes only where the line touches the body's
// quadric or passes through a point of one of its rim circles; these
// events bound exact shadow intervals on a scanline (span_shadows.cpp) and
// exact silhouettes on a sub-scanline (multiscan.cpp; docs/shadow-volumes.md
// "Exact intervals of curved occluders").
#pragma once

#include <vector>

#include "common/geometry.h"

namespace locus {

struct Pencil {
  Vec3 point, p0, p1;
};

// The coefficients {e2, e1, e0} of e(a) = e2 a^2 + e1 a + e0 for primitive
// prim (a sphere or cone, untransformed): the line at a meets the body's
// quadric (the whole sphere; the cone's infinite surface) where e(a) >= 0
// and touches it where e(a) = 0.
void pencil_quadric(const PrimitiveSet& prims, int prim, const Pencil& pen, double e[3]);

// The a where the pencil's line passes through a point of one of cone c's
// two rim circles, appended to `ev` (unsorted). False if the pencil's plane
// is parallel to the rims' planes (a rim would be met along an arc or not
// at all): the events are then unknown.
bool rim_events(const ConePrim& c, const Pencil& pen, std::vector<double>& ev);

}  // namespace locus
