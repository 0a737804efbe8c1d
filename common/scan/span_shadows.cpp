// SpanShadows: the shadows of scanline spans (paper §3.2 step 2), for point
// sampling and multi-scanning: the intervals kept per line, face and light,
// their candidates, and the lookups of the samples. The volumes come from
// shadow_volume.cpp; where a span meets one volume is in span_intervals.h.
#include "common/scan/span_shadows.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "common/base/check.h"
#include "common/geometry/bvh.h"
#include "common/prepare/prepared.h"
#include "common/prepare/shadow_candidates.h"
#include "common/scan/scanline.h"

namespace locus {
namespace {

// A span tests a candidate list this long directly; a longer one through
// the hierarchy.
constexpr int kWalkAbove = 8;

// A box's volume is tested with twice the slack of the volumes below it:
// it holds them with a margin (shadow_volume.cpp widens the boxes to the
// occluders' outlines), so whether a line or a group of lines reaches an
// occluder never hangs on rounding at a shared boundary, and the intervals
// do not depend on how the candidates were found.
constexpr double kNodeSlack = 2.0;

}  // namespace

SpanShadows::SpanShadows(const PreparedScene& ps, double y, Stats& stats)
    : ps_(ps), stats_(stats), lights_(static_cast<int>(ps.scene.lights.size())),
      slot_of_face_(ps.scan->faces.size(), -1), group_slot_of_face_(ps.scan->faces.size(), -1) {
  // The frame's shadow pass must be the volumes (shadows_by_rays decides).
  LOCUS_CHECK(ps.volumes);
  const CameraFrame& cam = ps.camera;
  a_line_lo_ = image_a(0.0);
  a_line_hi_ = image_a(cam.width);
  set_line(y);
}

void SpanShadows::set_line(double y) {
  const CameraFrame& cam = ps_.camera;
  b_ = (1.0 - 2.0 * y / cam.height) * cam.tan_half;
  face_ = -1;
  for (int k = 0; k < used_; ++k) slot_of_face_[slots_[k].face] = -1;
  used_ = 0;
  s_ = nullptr;
  // Groups lie at fixed rows (y in [k rows, (k + 1) rows), whatever band
  // the lines belong to), so a line's candidates, and with them its
  // intervals, are the same in every banding of the frame.
  if (group_rows_ > 0) {
    const double k = std::floor(y / group_rows_);
    if (k != group_k_) {
      for (int i = 0; i < group_used_; ++i) group_slot_of_face_[group_slots_[i].face] = -1;
      group_used_ = 0;
      group_k_ = k;
      group_b_hi_ = (1.0 - 2.0 * (k * group_rows_) / cam.height) * cam.tan_half;
      group_b_lo_ = (1.0 - 2.0 * ((k + 1) * group_rows_) / cam.height) * cam.tan_half;
    }
  }
}

double SpanShadows::image_a(double x) const {
  // The same expression as visible_faces() (scanline.cpp) at x = i + 0.5.
  const CameraFrame& cam = ps_.camera;
  return (2.0 * x / cam.width - 1.0) * cam.tan_half * cam.aspect;
}

double SpanShadows::image_x(double a) const {
  const CameraFrame& cam = ps_.camera;
  return 0.5 * cam.width * (1.0 + a / (cam.tan_half * cam.aspect));
}

void SpanShadows::begin_span(int face, double x_first, double x_last) {
  face_ = face;
  a_first_ = image_a(x_first);
  a_last_ = image_a(x_last);
  // A face visible in several spans of the line (a floor between objects)
  // has its intervals found once per line, over the whole line.
  if (const int k = slot_of_face_[face]; k >= 0) {
    s_ = &slots_[k];
    return;
  }
  if (used_ == static_cast<int>(slots_.size())) slots_.emplace_back();
  slot_of_face_[face] = used_;
  s_ = &slots_[used_++];
  s_->face = face;
  s_->done.assign(lights_, 0);
  s_->side.assign(lights_, 0);
  s_->iv.resize(lights_);
  s_->opaque.resize(lights_);
  s_->rest.resize(lights_);
  s_->rest_buckets.resize(lights_);
}

void SpanShadows::breakpoints(std::vector<double>& xs) {
  for (int j = 0; j < lights_; ++j) {
    if (!s_->done[j]) compute_light(j);
    for (const Interval& iv : s_->iv[j]) {
      for (const double a : {iv.lo, iv.hi}) {
        if (a > a_first_ && a < a_last_) xs.push_back(image_x(a));
      }
    }
  }
}

template <class Fn>
bool SpanShadows::visit_rest(int light, int i, Fn&& fn) const {
  const std::vector<Interval>& rest = s_->rest[light];
  const PixelBuckets& buckets = s_->rest_buckets[light];
  if (buckets.empty() || i < 0) {
    for (const Interval& iv : rest) {
      if (fn(iv)) return true;
    }
    return false;
  }
  return buckets.visit(i, [&](int k) { return fn(rest[k]); });
}

void SpanShadows::bucket_rest(int light) {
  // A floor under many curved occluders has dozens of them per light, and
  // each point would be checked against all: bucketed per pixel of the
  // line once, a point sees only those over its pixel.
  constexpr size_t kBucketAbove = 8;
  constexpr double kMargin = 1e-6;  // pixels, against rounding of x <-> a
  const std::vector<Interval>& rest = s_->rest[light];
  PixelBuckets& buckets = s_->rest_buckets[light];
  buckets.clear();
  if (rest.size() <= kBucketAbove) return;
  const int w = ps_.camera.width;
  buckets.build(w, static_cast<int>(rest.size()), [&](int k, auto&& fn) {
    const Interval& iv = rest[k];
    const double xl = image_x(iv.lo) - kMargin, xh = image_x(iv.hi) + kMargin;
    if (!iv.outside) {
      const int p0 = clamped_floor(xl, 0, w);
      const int p1 = clamped_floor(xh, -1, w - 1);
      for (int i = p0; i <= p1; ++i) fn(i);
      return;
    }
    // Holds the points outside [lo, hi]: every pixel not wholly inside.
    const double il = xl + 2 * kMargin, ih = xh - 2 * kMargin;
    for (int i = 0; i < w; ++i) {
      if (!(il < i && i + 1 < ih)) fn(i);
    }
  });
}

bool SpanShadows::uncertain(double x0, double x1) {
  const double a0 = image_a(x0), a1 = image_a(x1);
  // A piece lies inside one pixel (figures() cuts at pixel edges).
  const int i = clamped_floor(x0, -1, ps_.camera.width);
  const int pixel = x1 <= i + 1 ? std::min(i, ps_.camera.width - 1) : -1;
  for (int j = 0; j < lights_; ++j) {
    if (!s_->done[j]) compute_light(j);
    if (visit_rest(j, pixel, [&](const Interval& iv) {
          if (iv.decides) return false;
          // Where a non-deciding volume holds the points, an exact test does.
          return iv.outside ? (a0 < iv.lo || a1 > iv.hi) : (iv.lo < a1 && a0 < iv.hi);
        })) {
      return true;
    }
  }
  return false;
}

LightStates SpanShadows::states(double x) {
  LightStates st;
  const double a = image_a(x);
  const int pixel = clamped_floor(x, 0, ps_.camera.width - 1);
  const ScanFace& f = ps_.scan->faces[face_];
  const CameraFrame& cam = ps_.camera;
  thread_local std::vector<Crossing> crossings;
  // The face's point at a (docs/local.md), found only if an exact test
  // needs it.
  std::optional<Vec3> p;
  for (int j = 0; j < lights_ && j < 64; ++j) {
    if (!s_->done[j]) compute_light(j);
    crossings.clear();
    int tested = -1;
    bool opaque = false;
    Ray seg;
    const std::vector<std::pair<double, double>>& un = s_->opaque[j];
    auto it = std::upper_bound(un.begin(), un.end(), a,
                               [](double x, const std::pair<double, double>& r) { return x < r.first; });
    if (it != un.begin() && a <= std::prev(it)->second) {
      st.opaque |= uint64_t{1} << j;
      continue;
    }
    visit_rest(j, pixel, [&](const Interval& iv) {  // opaque intervals first
      if (((iv.lo <= a && a <= iv.hi) == iv.outside)) return false;
      if (iv.decides) {
        opaque = true;
        return true;
      }
      if (iv.prim == tested) return false;
      tested = iv.prim;
      if (!p) {
        p = face_point(f, cam.from, cam.w + b_ * cam.v + a * cam.u);
      }
      const Vec3 origin = *p + (s_->side[j] ? ps_.eps : -ps_.eps) * f.normal;
      seg = Ray{origin, ps_.volumes->lights[j].position - origin};
      if (exact_test(ps_, iv.prim, seg, crossings, stats_)) {
        opaque = true;
        return true;
      }
      return false;
    });
    add_light_state(st, j, opaque, ps_.scene, seg, crossings);
  }
  return st;
}

void add_light_state(LightStates& st, int j, bool opaque, const Scene& scene, const Ray& seg,
                     std::vector<Crossing>& crossings) {
  // Through glass beyond the critical angle nothing arrives (the dark
  // core of paper Fig. 8a): as dark as an opaque shadow, and its edge is
  // a change of state that bisection finds.
  if (!opaque && !crossings.empty() && segment_transmittance(scene, seg, crossings) == Color(0.0)) {
    opaque = true;
  }
  const uint64_t bit = uint64_t{1} << j;
  if (opaque) {
    st.opaque |= bit;
  } else if (!crossings.empty()) {
    // Through transparent occluders: which ones (eqs. (2), (3) vary
    // smoothly inside, and jump where the set changes).
    st.partial |= bit;
    for (const Crossing& c : crossings) {
      st.transparent = (st.transparent ^ static_cast<uint64_t>(c.leaf + 1)) * 1099511628211ull;
    }
  }
}

namespace {

// The candidate occluders that may shadow receiving primitive `prim` from
// light lv, to `occluder(c)`: without the search (configurations II and
// III: no boxes and no front/back relations) every occluder; else those of
// the receiver's list (paper §4.1, increasing), and a long list (a floor
// under many objects) narrowed by a walk of the hierarchy, which enters a
// box only where `box_meets(volume)` says the box's volume may meet the
// span or group of lines.
template <class BoxMeets, class Occluder>
void for_each_candidate(const PreparedScene& ps, int light, int prim, Stats& stats,
                        BoxMeets&& box_meets, Occluder&& occluder) {
  const LightVolumes& lv = ps.volumes->lights[light];
  if (!ps.volumes->search) {
    for (int c = 0; c < static_cast<int>(lv.occluders.size()); ++c) occluder(c);
    return;
  }
  const CandidateList& list = receiver_candidates(ps, light, prim);
  const int* cb = list.ids.data();
  const int* ce = cb + list.ids.size();
  if (ce - cb <= kWalkAbove) {
    for (const int* c = cb; c != ce; ++c) occluder(*c);
    return;
  }
  walk_bvh(
      ps.bvh,
      [&](int ni) {
        ++stats.tests_shadow_volume;
        return box_meets(lv.node_volume[ni]);
      },
      [&](int a) {
        if (std::binary_search(cb, ce, a)) occluder(a);
        return true;
      });
}

}  // namespace

SpanShadows::GroupSlot& SpanShadows::group_slot() {
  int gi = group_slot_of_face_[face_];
  if (gi >= 0) return group_slots_[gi];
  if (group_used_ == static_cast<int>(group_slots_.size())) group_slots_.emplace_back();
  gi = group_used_++;
  group_slot_of_face_[face_] = gi;
  GroupSlot& g = group_slots_[gi];
  g.face = face_;
  g.done.assign(lights_, 0);
  g.candidates.resize(lights_);
  g.vol_first.resize(lights_);
  g.volumes.resize(lights_);
  return g;
}

GroupRect SpanShadows::group_rect(int j) const {
  const ScanFace& f = ps_.scan->faces[face_];
  const CameraFrame& cam = ps_.camera;
  const Vec3& n = f.normal;
  const bool side = glm::dot(n, ps_.volumes->lights[j].position) - f.offset >= 0;  // as line_light
  GroupRect r;
  r.delta = (side ? ps_.eps : -ps_.eps) * n;
  r.num = f.offset - glm::dot(n, cam.from);
  r.sigma = r.num > 0 ? 1.0 : -1.0;
  r.nu = glm::dot(n, cam.u);
  r.nv = glm::dot(n, cam.v);
  r.nw = glm::dot(n, cam.w);
  // The rectangle: the group's rows and the face's own extent in the image
  // (its spans lie inside it), so a small face seen on one or two lines
  // does not collect the occluders of a whole strip of the image.
  double x0 = kInf, x1 = -kInf;
  for (const Vec2& q : f.outline) {
    x0 = std::min(x0, q.x);
    x1 = std::max(x1, q.x);
  }
  constexpr double kMargin = 1e-3;  // pixels, far beyond rounding
  x0 = std::max(x0 - kMargin, 0.0);
  x1 = std::min(x1 + kMargin, static_cast<double>(cam.width));
  double y0 = std::max(f.ymin - kMargin, group_k_ * group_rows_);
  double y1 = std::min(f.ymax + kMargin, (group_k_ + 1) * group_rows_);
  // Not expected (the face meets a line of the group): the whole strip.
  if (!(x0 <= x1)) x0 = 0, x1 = cam.width;
  if (!(y0 <= y1)) y0 = group_k_ * group_rows_, y1 = (group_k_ + 1) * group_rows_;
  r.a0 = image_a(x0);
  r.a1 = image_a(x1);
  r.b0 = (1.0 - 2.0 * y1 / cam.height) * cam.tan_half;
  r.b1 = (1.0 - 2.0 * y0 / cam.height) * cam.tan_half;
  return r;
}

const SpanShadows::GroupSlot& SpanShadows::group_candidates(int j) {
  GroupSlot& g = group_slot();
  if (g.done[j]) return g;
  g.done[j] = 1;
  std::vector<int>& out = g.candidates[j];
  std::vector<int>& vol_first = g.vol_first[j];
  std::vector<int>& vols = g.volumes[j];
  out.clear();
  vol_first.assign(1, 0);
  vols.clear();
  const LightVolumes& lv = ps_.volumes->lights[j];
  const GroupRect r = group_rect(j);
  // An occluder stays a candidate if its bound and one of its volumes may
  // meet the rectangle (the tests compute_light's lines make, with slack
  // at least theirs). Its volumes that miss the rectangle give no interval
  // on any line of the group inside the face, so the lines skip them (a
  // concave polygon cut into many convex pieces: SPD gears). The walk is
  // the lines' own, with the rectangle: its order is kept.
  for_each_candidate(
      ps_, j, ps_.scan->faces[face_].prim, stats_,
      [&](int v) { return meets_rect(lv.set, v, r, kNodeSlack * lv.slack); },
      [&](int c) {
        const LightVolumes::Occluder& oc = lv.occluders[c];
        ++stats_.tests_shadow_volume;
        if (oc.bound >= 0 && !meets_rect(lv.set, oc.bound, r, lv.slack)) return;
        const size_t before = vols.size();
        for (int v = oc.first; v < oc.first + oc.count; ++v) {
          if (meets_rect(lv.set, v, r, lv.slack)) vols.push_back(v);
        }
        if (vols.size() == before) return;
        out.push_back(c);
        vol_first.push_back(static_cast<int>(vols.size()));
      });
  return g;
}

SpanShadows::LineLight SpanShadows::line_light(int j) {
  const ScanFace& f = ps_.scan->faces[face_];
  const CameraFrame& cam = ps_.camera;
  const LightVolumes& lv = ps_.volumes->lights[j];
  const Vec3& n = f.normal;
  LineLight ll;
  // The shadow-ray origin of a point P of the face is P + delta, offset to
  // the light's side (Tracer::offset).
  s_->side[j] = glm::dot(n, lv.position) - f.offset >= 0;
  const Vec3 delta = (s_->side[j] ? ps_.eps : -ps_.eps) * n;
  SpanLine& l = ll.line;
  l.delta = delta;
  l.b = b_;
  l.eye_delta = cam.from + delta;
  l.w_bv = cam.w + b_ * cam.v;
  l.u = cam.u;
  l.num = f.offset - glm::dot(n, cam.from);
  l.sigma = l.num > 0 ? 1.0 : -1.0;
  l.nw = glm::dot(n, l.w_bv);
  l.nu = glm::dot(n, cam.u);
  l.a_first = a_line_lo_;
  l.a_last = a_line_hi_;
  // Opaque spheres and cones between the face and the light get exact
  // intervals (the pencil from the light through the line's origins,
  // span_intervals.h); heights are above the face, on the light's side.
  ll.sigma = s_->side[j] ? 1.0 : -1.0;
  ll.h_light = ll.sigma * (glm::dot(n, lv.position) - f.offset);
  const Vec3 g = l.eye_delta - lv.position;
  ll.pen = Pencil{lv.position, l.nw * g + l.num * l.w_bv, l.nu * g + l.num * l.u};
  return ll;
}

template <class EachVolume>
void SpanShadows::occluder_intervals(int j, const LineLight& ll, int c, EachVolume&& each_volume) {
  const LightVolumes& lv = ps_.volumes->lights[j];
  const LightVolumes::Occluder& oc = lv.occluders[c];
  const SpanLine& l = ll.line;
  std::vector<Interval>& out = s_->iv[j];
  if (oc.bound >= 0) {
    ++stats_.tests_shadow_volume;
    if (!meets_span(lv.set, oc.bound, l, lv.slack)) return;
  }
  const ScanFace& f = ps_.scan->faces[face_];
  if (!oc.decides && is_opaque(ps_, c) &&
      between_origins_and_light(ps_.prims, c, f.normal, f.offset, ll.sigma, ps_.eps, ll.h_light,
                                lv.slack) &&
      exact_intervals(ps_.prims, c, ll.pen, l.a_first, l.a_last, events_, stats_, out)) {
    return;
  }
  const double slack = oc.decides ? 0.0 : lv.slack;
  each_volume([&](int v) {
    ++stats_.tests_shadow_volume;
    const ShadowVolume& vol = lv.set.volumes[v];
    if (vol.kind == VolumeKind::kEverywhere) {
      out.push_back(Interval{c, oc.decides, l.a_first, l.a_last, false});
      return;
    }
    double lo, hi;
    inside_range(lv.set, vol, l, slack, vol.kind == VolumeKind::kConvex, &lo, &hi);
    if (vol.kind == VolumeKind::kConvex) {
      if (lo > hi || lo > l.a_last || hi < l.a_first) return;
      out.push_back(Interval{c, oc.decides, lo, hi, false});
    } else {
      // kOutside: shadow outside [lo, hi].
      if (lo <= l.a_first && hi >= l.a_last) return;
      out.push_back(Interval{c, oc.decides, lo, hi, true});
    }
  });
}

void SpanShadows::opaque_first(int j) {
  std::vector<Interval>& out = s_->iv[j];
  std::stable_partition(out.begin(), out.end(), [](const Interval& i) { return i.decides; });
  // The opaque union and the rest (states(), uncertain()): on a floor
  // under many polygons a point is looked up among hundreds of
  // intervals; in the union that takes a binary search.
  std::vector<std::pair<double, double>>& un = s_->opaque[j];
  std::vector<Interval>& rest = s_->rest[j];
  un.clear();
  rest.clear();
  for (const Interval& iv : out) {
    if (iv.decides && !iv.outside) {
      un.emplace_back(iv.lo, iv.hi);
    } else {
      rest.push_back(iv);
    }
  }
  std::sort(un.begin(), un.end());
  size_t m = 0;
  for (size_t k = 0; k < un.size(); ++k) {
    if (m > 0 && un[k].first <= un[m - 1].second) {
      un[m - 1].second = std::max(un[m - 1].second, un[k].second);
    } else {
      un[m++] = un[k];
    }
  }
  un.resize(m);
  bucket_rest(j);
}

void SpanShadows::compute_light(int j) {
  s_->done[j] = 1;
  s_->iv[j].clear();
  const LineLight ll = line_light(j);
  const LightVolumes& lv = ps_.volumes->lights[j];
  if (group_rows_ > 0) {
    // The group's candidates, each with its volumes that may meet the group.
    const GroupSlot& g = group_candidates(j);
    const std::vector<int>& cands = g.candidates[j];
    const std::vector<int>& vf = g.vol_first[j];
    const int* vols = g.volumes[j].data();
    for (size_t k = 0; k < cands.size(); ++k) {
      occluder_intervals(j, ll, cands[k], [&](auto&& fn) {
        for (int q = vf[k]; q < vf[k + 1]; ++q) fn(vols[q]);
      });
    }
  } else {
    // The line's own candidates, each with all its volumes; the hierarchy's
    // boxes tested by their volumes against the span.
    for_each_candidate(
        ps_, j, ps_.scan->faces[face_].prim, stats_,
        [&](int v) { return meets_span(lv.set, v, ll.line, kNodeSlack * lv.slack); },
        [&](int c) {
          const LightVolumes::Occluder& oc = lv.occluders[c];
          occluder_intervals(j, ll, c, [&](auto&& fn) {
            for (int v = oc.first; v < oc.first + oc.count; ++v) fn(v);
          });
        });
  }
  // Opaque intervals first: a pixel in one needs no exact test.
  opaque_first(j);
}

std::optional<Color> SpanShadows::transmittance(const Vec3& p, const Vec3& origin, int light) {
  if (light >= lights_) return std::nullopt;
  if (!s_->done[light]) compute_light(light);
  const ScanFace& f = ps_.scan->faces[face_];
  // The intervals hold for origins on the light's side of the face; a
  // light almost in the face's plane may put a pixel's origin on the other.
  if ((glm::dot(origin - p, f.normal) > 0) != static_cast<bool>(s_->side[light])) {
    // A shadow ray decides (Tracer::transmittance), or the volumes' search.
    if (!ps_.points_search_volumes()) return std::nullopt;
    return volume_transmittance(ps_, origin, light, f.prim, stats_, nullptr);
  }
  const double a = a_;
  const Ray seg{origin, ps_.volumes->lights[light].position - origin};
  thread_local std::vector<Crossing> crossings;
  crossings.clear();
  int tested = -1;
  for (const Interval& iv : s_->iv[light]) {
    const bool in = (iv.lo <= a && a <= iv.hi) != iv.outside;
    if (!in) continue;
    if (iv.decides) return Color(0.0);  // opaque: no ray (paper §3.2)
    if (iv.prim == tested) continue;    // another piece of the same body
    if (tested < 0) ++stats_.rays_shadow;
    tested = iv.prim;
    if (exact_test(ps_, iv.prim, seg, crossings, stats_)) return Color(0.0);
  }
  return segment_transmittance(ps_.scene, seg, crossings);
}

}  // namespace locus
