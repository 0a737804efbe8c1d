// The shadows of the spans of a scanline (paper §3.2 step 2), from the
// shadow volumes of common/prepare/shadow_volume.h (docs/shadow-volumes.md,
// docs/multiscan.md); where one span meets one occluder is in
// span_intervals.h.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "common/geometry/pencil.h"
#include "common/prepare/shadow_volume.h"
#include "common/scan/pixel_buckets.h"
#include "common/scan/span_intervals.h"
#include "common/trace/raytrace.h"
#include "common/trace/shadow_search.h"

namespace locus {

// What reaches a point from each of the first 64 lights (bit j: light j):
// blocked by an opaque occluder, or through transparent ones (`transparent`
// hashes which), else unshadowed. Equal states shade alike.
struct LightStates {
  uint64_t opaque = 0;
  uint64_t partial = 0;
  uint64_t transparent = 0;
  bool operator==(const LightStates&) const = default;
};

// Light j's part of `st` (j < 64) from what its shadow segment `seg` met:
// an opaque occluder (`opaque`), the transparent surfaces of `crossings`
// (eqs. (2), (3)), or nothing. Glass that passes nothing counts as opaque.
void add_light_state(LightStates& st, int j, bool opaque, const Scene& scene, const Ray& seg,
                     std::vector<Crossing>& crossings);

// The shadows of the spans of one row (paper §3.2 step 2): for a visible
// span of a flat face, each candidate occluder's volume meets the segment
// the scan plane cuts from the face in an interval, found once per span and
// light; a pixel in an opaque interval is in shadow without any ray. An
// opaque sphere or cone between the face and the light has its exact
// intervals (common/geometry/pencil.h). Inside the interval of another curved
// body's bounding polyhedron or of a transparent occluder, the exact
// segment test decides per pixel (t_pj by eqs. (2), (3)).
class SpanShadows : public KnownShadows {
 public:
  // Spans on the sample line at image row coordinate y (row j's pixel
  // centres: y = j + 0.5; multi-scanning: any sub-scanline). `ps` must have
  // its shadow volumes (a frame whose shadows are found by rays has none).
  SpanShadows(const PreparedScene& ps, double y, Stats& stats);
  // Moves to another sample line, keeping the allocations.
  void set_line(double y);
  // Multi-scanning: the lines come in increasing y, several per pixel row.
  // Each span's candidate occluders are then found once per group of lines
  // (rows [k rows, (k + 1) rows], the hierarchy walked with the group's
  // image rectangle), and each line only computes its intervals from them.
  // 0 (the default): every line walks the hierarchy itself. Call before
  // set_line.
  void set_group_rows(double rows) { group_rows_ = rows; }

  // The next samples to shade lie on scanline face `face` (ScanScene::faces)
  // at image x in [x_first, x_last]; intervals are clipped to that range.
  void begin_span(int face, double x_first, double x_last);
  void begin_span(int face, int x0, int x1) { begin_span(face, x0 + 0.5, x1 - 0.5); }
  // The sample about to be shaded.
  void set_x(double x) { a_ = image_a(x); }
  void set_pixel(int x) { set_x(x + 0.5); }

  std::optional<Color> transmittance(const Vec3& p, const Vec3& origin, int light) override;

  // Multi-scanning (paper §3.3): the x where the span's shadow intervals
  // begin or end, inside (x_first, x_last), appended to `xs`.
  void breakpoints(std::vector<double>& xs);
  // Whether some point in (x0, x1) needs an exact test (it lies in the
  // volume of a curved body's bounding polyhedron or of a transparent
  // occluder), so its shadows may change inside without a breakpoint.
  bool uncertain(double x0, double x1);
  // The state of the first 64 lights at x.
  LightStates states(double x);

 private:
  using Interval = SpanInterval;
  // The intervals of `light` on the current face and line (paper §3.2 step
  // 2), in steps: the line of origins (line_light), each candidate
  // occluder's intervals (occluder_intervals), then opaque_first.
  void compute_light(int light);
  // The span's line of shadow-ray origins for one light, and what the exact
  // intervals of curved occluders need: the pencil from the light through
  // those origins, and the light's height above the face on its side.
  struct LineLight {
    SpanLine line;
    Pencil pen;
    double sigma, h_light;
  };
  LineLight line_light(int light);
  // Appends to iv[light] occluder c's intervals: exact ones for an opaque
  // sphere or cone between the face and the light, else those of each of
  // its volumes that `each_volume(fn)` hands to fn (all of them, or a
  // group's list).
  template <class EachVolume>
  void occluder_intervals(int light, const LineLight& ll, int c, EachVolume&& each_volume);
  // Orders iv[light] opaque first and derives opaque[light], rest[light]
  // and its buckets from it.
  void opaque_first(int light);
  double image_a(double x) const;
  double image_x(double a) const;

  const PreparedScene& ps_;
  Stats& stats_;
  double b_ = 0;  // image-plane coordinate of the sample line
  int lights_ = 0;
  int face_ = -1;
  double a_first_ = 0, a_last_ = 0, a_ = 0;
  double a_line_lo_ = 0, a_line_hi_ = 0;  // the whole sample line
  // Per face met on this line: per light, whether its intervals are
  // computed, whether shadow-ray origins lie on the face's front side, and
  // the intervals.
  struct Slot {
    int face = -1;
    std::vector<char> done;
    std::vector<char> side;
    std::vector<std::vector<Interval>> iv;
    // Per light, derived from iv for states() and uncertain(): the union of
    // the opaque convex intervals as disjoint closed ranges in increasing
    // order, and the other intervals (exact tests, kOutside).
    std::vector<std::vector<std::pair<double, double>>> opaque;
    std::vector<std::vector<Interval>> rest;
    // Per light with a long `rest`: its intervals that may hold a point of
    // each pixel, in rest's order (empty: scan it all).
    std::vector<PixelBuckets> rest_buckets;
  };
  // The intervals of rest[light] that may hold points of pixel i (all of
  // them when it is short), in rest's order, to fn until it returns true.
  template <class Fn>
  bool visit_rest(int light, int i, Fn&& fn) const;
  void bucket_rest(int light);
  std::vector<Slot> slots_;
  int used_ = 0;
  Slot* s_ = nullptr;
  std::vector<int> slot_of_face_;  // index into slots_, or -1

  // Groups of lines: y in [k rows, (k + 1) rows] (k = group_k_); per face
  // met, per light, whether its candidates are found, and the candidates.
  double group_rows_ = 0;
  double group_k_ = -1;
  double group_b_lo_ = 0, group_b_hi_ = 0;  // image-plane b of the group
  struct GroupSlot {
    int face = -1;
    std::vector<char> done;
    std::vector<std::vector<int>> candidates;
    // Per light: the volumes of candidate k that may meet the group's
    // rectangle are volumes[vol_first[k], vol_first[k + 1]).
    std::vector<std::vector<int>> vol_first, volumes;
  };
  std::vector<GroupSlot> group_slots_;
  // face_'s slot of the current group, made on first use.
  GroupSlot& group_slot();
  // The image rectangle of face_ on the current group of lines, with the
  // offset of `light`'s shadow-ray origins.
  GroupRect group_rect(int light) const;
  // The candidate occluders of face_ and light j on the current group of
  // lines, in the order of the per-line walk, with the volumes of each that
  // may meet the group (GroupSlot).
  const GroupSlot& group_candidates(int light);
  int group_used_ = 0;
  std::vector<int> group_slot_of_face_;
  std::vector<double> events_;  // compute_light's scratch
};

}  // namespace locus
