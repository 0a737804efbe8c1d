// Where one span meets one occluder (paper §3.2 step 2), the geometry under
// SpanShadows (span_shadows.h), which keeps the bookkeeping per line, face
// and light: the line of a span's shadow-ray origins (SpanLine) and the
// range of it inside a shadow volume (inside_range, meets_span); whether a
// group of lines' image rectangle may meet a volume (GroupRect, meets_rect);
// and the exact intervals of opaque spheres and cones
// (between_origins_and_light, exact_intervals; docs/shadow-volumes.md
// "Exact intervals of curved occluders").
#pragma once

#include <algorithm>
#include <vector>

#include "common/base/params.h"
#include "common/geometry/pencil.h"
#include "common/prepare/shadow_volume.h"

namespace locus {

// Where a span meets one volume: lo <= a <= hi in the image-plane
// coordinate a of the sample direction (outside that range for a kOutside
// volume). `decides`: a point inside is shadowed by `prim` without an exact
// test.
struct SpanInterval {
  int prim;
  bool decides;
  double lo, hi;
  bool outside;
};

// A span's line on the face, for intervals: the shadow-ray origins of the
// face's points on the scan plane are O(a) = E + delta + s(a) D(a), with
// D(a) = w + a u + b v and s(a) = num / (nw + a nu) > 0 (docs/local.md).
struct SpanLine {
  Vec3 delta;      // the shadow-ray origins' offset from the face
  double b;        // the scan plane's image coordinate
  Vec3 eye_delta;  // E + delta
  Vec3 w_bv;       // w + b v
  Vec3 u;
  double num, nw, nu, sigma;
  double a_first, a_last;  // the span's first and last pixel
};

// The range [lo, hi] of a where O(a) lies inside every plane of volume v
// (each moved out by `slack`). A plane m . x <= h at O(a), multiplied by
// the denominator nw + a nu (of sign sigma), reads alpha + beta a <= 0:
// linear in a. Stops early once the range misses the span if `clip`.
// Inline: it runs per volume and span, in the innermost loop.
inline void inside_range(const VolumeSet& set, const ShadowVolume& vol, const SpanLine& l,
                         double slack, bool clip, double* lo_out, double* hi_out) {
  double lo = -kInf, hi = kInf;
  for (int i = vol.first; i < vol.first + vol.count; ++i) {
    const HalfSpace& p = set.planes[i];
    // m . (E + delta) - h, m . (w + b v) and m . u, from the plane's
    // products with the camera frame (VolumeSet::cam).
    const VolumeSet::CameraDots& k = set.cam[i];
    const double c0 = k.me + glm::dot(p.m, l.delta) - slack;
    const double c1 = k.mw + l.b * k.mv;
    const double c2 = k.mu;
    const double alpha = l.sigma * (c0 * l.nw + l.num * c1);
    const double beta = l.sigma * (c0 * l.nu + l.num * c2);
    if (beta > 0) {
      hi = std::min(hi, -alpha / beta);
    } else if (beta < 0) {
      lo = std::max(lo, -alpha / beta);
    } else if (alpha > 0) {
      lo = kInf;
    }
    if (clip && (lo > hi || lo > l.a_last || hi < l.a_first)) break;
  }
  *lo_out = lo;
  *hi_out = hi;
}

// Whether volume v (its planes moved out by `slack`) may hold a shadow-ray
// origin of the span; only a kConvex volume can tell it does not.
inline bool meets_span(const VolumeSet& set, int v, const SpanLine& l, double slack) {
  const ShadowVolume& vol = set.volumes[v];
  if (vol.kind != VolumeKind::kConvex) return true;
  double lo, hi;
  inside_range(set, vol, l, slack, true, &lo, &hi);
  return !(lo > hi || lo > l.a_last || hi < l.a_first);
}

// A group of lines (multi-scanning): the face's points seen through the
// image rectangle [a0, a1] x [b0, b1], with shadow-ray origins
// O(a, b) = E + delta + s D(a, b), D = w + a u + b v, s = num / (n . D).
struct GroupRect {
  Vec3 delta;
  double num, sigma, nu, nv, nw;
  double a0, a1, b0, b1;
};

// Whether volume v may hold some O(a, b) of the rectangle (each plane moved
// out by `slack`). Conservative: no line of the group loses an interval its
// own walk would find.
bool meets_rect(const VolumeSet& set, int v, const GroupRect& r, double slack);

// Whether prim is a plain quadric (common/geometry/pencil.h) lying strictly
// between the heights h0 (the shadow-ray origins) and hl (the light), by
// `margin`; heights are sigma (n . x - offset). Then a line of the pencil
// from the light through the origins that meets the body does so inside the
// segment from the origin to the light, and exact_intervals gives the
// shadow ray's answer (eqs. (2), (3)).
bool between_origins_and_light(const PrimitiveSet& prims, int prim, const Vec3& n, double offset,
                               double sigma, double h0, double hl, double margin);

// The exact shadow intervals of opaque plain quadric `prim` on the line's
// parameters [a_first, a_last], where `pen` is the pencil from the light
// through the line's shadow-ray origins, appended to `out` (deciding, one
// per shadowed part); false, with nothing appended, if they cannot be found.
// `events` is scratch.
bool exact_intervals(const PrimitiveSet& prims, int prim, const Pencil& pen, double a_first,
                     double a_last, std::vector<double>& events, Stats& stats,
                     std::vector<SpanInterval>& out);

}  // namespace locus
