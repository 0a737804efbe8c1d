// A pencil of lines: the lines through one point P (a light, or the eye)
// and the points of another line, whose directions are p0 + a p1 for a
// real parameter a (an image coordinate). Along a pencil, whether a line
// meets a sphere or cone changes only where the line touches the body's
// quadric or passes through a point of one of its rim circles; these
// events bound exact shadow intervals on a scanline (span_intervals.cpp) and
// exact silhouettes on a sub-scanline (sub_line.cpp; docs/shadow-volumes.md
// "Exact intervals of curved occluders").
#pragma once

#include <vector>

#include "common/geometry/geometry.h"

namespace locus {

struct Pencil {
  Vec3 point, p0, p1;
};

// Whether prim is a sphere or cone without a transform: the bodies whose
// events along a pencil are computed here (and whose solids
// beyond_support knows).
inline bool plain_quadric(const PrimitiveSet& prims, int prim) {
  const PrimRef& ref = prims.prims[prim];
  if (ref.kind == PrimKind::kSphere) return prims.spheres[ref.index].frame.identity;
  return ref.kind == PrimKind::kCone && prims.cones[ref.index].frame.identity;
}

// For plain quadric `prim`: the coefficients {e2, e1, e0} of e(a) = e2 a^2 +
// e1 a + e0, where the line at a meets the body's quadric (the whole
// sphere; the cone's infinite surface) where e(a) >= 0 and touches it where
// e(a) = 0; and the events, appended to `ev` unsorted: e's roots, and for a
// cone the a where the line passes through a point of one of its rim
// circles. Between two consecutive events, whether the line meets the body
// does not change. False (nothing appended) if the pencil's plane is
// parallel to a cone's rims (a rim would be met along an arc or not at
// all): the events are then unknown.
bool pencil_events(const PrimitiveSet& prims, int prim, const Pencil& pen, double e[3],
                   std::vector<double>& ev);

}  // namespace locus
