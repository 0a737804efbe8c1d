// SpanShadows: the shadows of scanline spans (paper §3.2 step 2), for point
// sampling and multi-scanning. The volumes come from shadow_volume.cpp.
#include "common/scan/span_shadows.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "common/geometry/pencil.h"
#include "common/prepare/prepared.h"
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
      const int p0 = std::max(0, static_cast<int>(std::floor(xl)));
      const int p1 = std::min(w - 1, static_cast<int>(std::floor(xh)));
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
  const int i = static_cast<int>(std::floor(x0));
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
  const int pixel = std::clamp(static_cast<int>(std::floor(x)), 0, ps_.camera.width - 1);
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
        const Vec3 d = cam.w + b_ * cam.v + a * cam.u;
        p = cam.from + ((f.offset - glm::dot(f.normal, cam.from)) / glm::dot(f.normal, d)) * d;
      }
      const Vec3 origin = *p + (s_->side[j] ? ps_.eps : -ps_.eps) * f.normal;
      seg = Ray{origin, ps_.volumes->lights[j].position - origin};
      if (exact_test(ps_, iv.prim, seg, crossings, stats_)) {
        opaque = true;
        return true;
      }
      return false;
    });
    // Through glass beyond the critical angle nothing arrives (the dark
    // core of paper Fig. 8a): as dark as an opaque shadow, and its edge is
    // a change of state that bisection finds.
    if (!opaque && !crossings.empty() &&
        segment_transmittance(ps_.scene, seg, crossings) == Color(0.0)) {
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
  return st;
}

namespace {

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

// Exact shadow intervals of opaque spheres and cones (docs/shadow-volumes.md
// "Exact intervals of curved occluders"). The lines through the light L
// and the span's shadow-ray origins O(a) form a pencil (common/geometry/pencil.h),
// with directions (nw + a nu) (O(a) - L) = p0 + a p1, linear in a. The
// line at a meets the body's quadric where e(a) >= 0: for a sphere that is
// the shadow. For a cone or cylinder, whether the line meets the body
// between its rims changes only at those ends or where it passes through a
// point of a rim circle; between two such events, one line test decides.
// Either way the result is the shadow ray's (eqs. (2), (3)) when the body
// lies strictly between the origins and the light: a line that meets it
// then does so inside the segment from O(a) to L
// (SpanShadows::compute_light's exact_intervals).
//
// Whether prim is a plain quadric (common/geometry/pencil.h) lying strictly between
// the heights h0 (the shadow-ray origins) and hl (the light), by `margin`;
// heights are sigma (n . x - offset).
bool between_origins_and_light(const PrimitiveSet& prims, int prim, const Vec3& n, double offset,
                               double sigma, double h0, double hl, double margin) {
  if (!plain_quadric(prims, prim)) return false;
  const PrimRef& ref = prims.prims[prim];
  double lo, hi;
  if (ref.kind == PrimKind::kSphere) {
    const SpherePrim& s = prims.spheres[ref.index];
    const double h = sigma * (glm::dot(n, s.s.center) - offset);
    lo = h - s.s.radius;
    hi = h + s.s.radius;
  } else {
    const ConePrim& c = prims.cones[ref.index];
    // A rim circle of radius r reaches r sqrt(1 - (n . axis)^2) off its centre's height.
    const double na = glm::dot(n, c.axis.a);
    const double spread = std::sqrt(std::max(0.0, 1.0 - na * na));
    const double hb = sigma * (glm::dot(n, c.c.base) - offset);
    const double ha = hb + sigma * na * c.axis.h;
    const double eb = c.c.base_radius * spread, ea = c.c.apex_radius * spread;
    lo = std::min(hb - eb, ha - ea);
    hi = std::max(hb + eb, ha + ea);
  }
  return lo > h0 + margin && hi < hl - margin;
}

// The range [lo, hi] of a where O(a) lies inside every plane of volume v
// (each moved out by `slack`). A plane m . x <= h at O(a), multiplied by
// the denominator nw + a nu (of sign sigma), reads alpha + beta a <= 0:
// linear in a. Stops early once the range misses the span if `clip`.
void inside_range(const VolumeSet& set, const ShadowVolume& vol, const SpanLine& l, double slack,
                  bool clip, double* lo_out, double* hi_out) {
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

bool meets_span(const VolumeSet& set, int v, const SpanLine& l, double slack) {
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

// Whether volume v may hold some O(a, b) of the rectangle. A plane
// m . x <= h + slack at O, multiplied by n . D (of sign sigma wherever the
// face is in front of the eye), reads K0 + Ka a + Kb b <= 0: a half-plane
// of the image. The rectangle is clipped by each (Sutherland-Hodgman); the
// volume misses it when nothing is left. Conservative: a vertex beyond a
// plane by no more than rounding is kept, so no line of the group loses an
// interval its own walk would find.
bool meets_rect(const VolumeSet& set, int v, const GroupRect& r, double slack) {
  const ShadowVolume& vol = set.volumes[v];
  if (vol.kind != VolumeKind::kConvex) return true;
  constexpr int kMax = 40;
  double pa[2][kMax], pb[2][kMax];
  int n = 4;
  pa[0][0] = r.a0, pb[0][0] = r.b0;
  pa[0][1] = r.a1, pb[0][1] = r.b0;
  pa[0][2] = r.a1, pb[0][2] = r.b1;
  pa[0][3] = r.a0, pb[0][3] = r.b1;
  const double amax = std::max(std::abs(r.a0), std::abs(r.a1));
  const double bmax = std::max(std::abs(r.b0), std::abs(r.b1));
  // Plane i as K0 + Ka a + Kb b <= tol over the rectangle.
  struct Line {
    double k0, ka, kb, tol;
  };
  auto line_of = [&](int i) {
    const VolumeSet::CameraDots& k = set.cam[i];
    const double c0 = k.me + glm::dot(set.planes[i].m, r.delta) - slack;
    Line q;
    q.k0 = r.sigma * (c0 * r.nw + r.num * k.mw);
    q.ka = r.sigma * (c0 * r.nu + r.num * k.mu);
    q.kb = r.sigma * (c0 * r.nv + r.num * k.mv);
    q.tol = 1e-9 * (std::abs(q.k0) + std::abs(q.ka) * amax + std::abs(q.kb) * bmax);
    return q;
  };
  // Most volumes that miss lie wholly beyond one of their planes: the four
  // corners tell, with no clipping (a linear function's least value on a
  // rectangle is at a corner).
  for (int i = vol.first; i < vol.first + vol.count; ++i) {
    const Line q = line_of(i);
    if (q.k0 + std::min(q.ka * r.a0, q.ka * r.a1) + std::min(q.kb * r.b0, q.kb * r.b1) - q.tol > 0) {
      return false;
    }
  }
  int cur = 0;
  for (int i = vol.first; i < vol.first + vol.count; ++i) {
    if (n + 1 > kMax) return true;
    const Line q = line_of(i);
    const double k0 = q.k0, ka = q.ka, kb = q.kb, tol = q.tol;
    const double* xa = pa[cur];
    const double* xb = pb[cur];
    double* ya = pa[1 - cur];
    double* yb = pb[1 - cur];
    int m = 0;
    double vp = k0 + ka * xa[n - 1] + kb * xb[n - 1] - tol;
    for (int q = 0, p = n - 1; q < n; p = q++) {
      const double vq = k0 + ka * xa[q] + kb * xb[q] - tol;
      if ((vp <= 0) != (vq <= 0)) {
        const double t = vp / (vp - vq);
        ya[m] = xa[p] + t * (xa[q] - xa[p]);
        yb[m] = xb[p] + t * (xb[q] - xb[p]);
        ++m;
      }
      if (vq <= 0) {
        ya[m] = xa[q];
        yb[m] = xb[q];
        ++m;
      }
      vp = vq;
    }
    if (m == 0) return false;
    n = m;
    cur = 1 - cur;
  }
  return true;
}

}  // namespace

const SpanShadows::GroupSlot& SpanShadows::group_candidates(int j) {
  int gi = group_slot_of_face_[face_];
  if (gi < 0) {
    if (group_used_ == static_cast<int>(group_slots_.size())) group_slots_.emplace_back();
    gi = group_used_++;
    group_slot_of_face_[face_] = gi;
    GroupSlot& g = group_slots_[gi];
    g.face = face_;
    g.done.assign(lights_, 0);
    g.candidates.resize(lights_);
    g.vol_first.resize(lights_);
    g.volumes.resize(lights_);
  }
  GroupSlot& g = group_slots_[gi];
  std::vector<int>& out = g.candidates[j];
  if (g.done[j]) return g;
  g.done[j] = 1;
  out.clear();
  std::vector<int>& vol_first = g.vol_first[j];
  std::vector<int>& vols = g.volumes[j];
  vol_first.assign(1, 0);
  vols.clear();
  const ScanFace& f = ps_.scan->faces[face_];
  const CameraFrame& cam = ps_.camera;
  const LightVolumes& lv = ps_.volumes->lights[j];
  const Vec3& n = f.normal;
  const bool side = glm::dot(n, lv.position) - f.offset >= 0;  // as compute_light
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
  // An occluder stays a candidate if its bound and one of its volumes may
  // meet the rectangle (the tests compute_light's lines make, with slack
  // at least theirs). Its volumes that miss the rectangle give no interval
  // on any line of the group inside the face, so the lines skip them (a
  // concave polygon cut into many convex pieces: SPD gears).
  auto occluder = [&](int c) {
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
  };
  if (!ps_.volumes->search) {
    for (int c = 0; c < static_cast<int>(lv.occluders.size()); ++c) occluder(c);
    return g;
  }
  const int* cb = lv.candidates.data() + lv.candidate_first[f.prim];
  const int* ce = lv.candidates.data() + lv.candidate_first[f.prim + 1];
  if (ce - cb <= kWalkAbove) {
    for (const int* c = cb; c != ce; ++c) occluder(*c);
    return g;
  }
  // The walk of compute_light, with the rectangle: its order is kept.
  int stack[128];
  int sp = 0;
  stack[sp++] = 0;
  while (sp) {
    const int ni = stack[--sp];
    ++stats_.tests_shadow_volume;
    if (!meets_rect(lv.set, lv.node_volume[ni], r, kNodeSlack * lv.slack)) continue;
    const BvhNode& node = ps_.bvh.nodes[ni];
    if (node.count == 0) {
      stack[sp++] = node.first;
      stack[sp++] = ni + 1;
      continue;
    }
    for (int k = node.first; k < node.first + node.count; ++k) {
      const int a = ps_.bvh.order[k];
      if (std::binary_search(cb, ce, a)) occluder(a);
    }
  }
  return g;
}

void SpanShadows::compute_light(int j) {
  s_->done[j] = 1;
  std::vector<Interval>& out = s_->iv[j];
  out.clear();
  const ScanFace& f = ps_.scan->faces[face_];
  const CameraFrame& cam = ps_.camera;
  const LightVolumes& lv = ps_.volumes->lights[j];
  const Vec3& n = f.normal;
  // The shadow-ray origin of a point P of the face is P + delta, offset to
  // the light's side (Tracer::offset).
  s_->side[j] = glm::dot(n, lv.position) - f.offset >= 0;
  const Vec3 delta = (s_->side[j] ? ps_.eps : -ps_.eps) * n;
  SpanLine l;
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
  // intervals (the pencil from the light through the line's origins, see
  // above); heights are above the face, on the light's side.
  const double sigma = s_->side[j] ? 1.0 : -1.0;
  const double h_light = sigma * (glm::dot(n, lv.position) - f.offset);
  const Vec3 g = l.eye_delta - lv.position;
  const Pencil pen{lv.position, l.nw * g + l.num * l.w_bv, l.nu * g + l.num * l.u};
  // The exact intervals of occluder c on the line, appended to `out`;
  // false if they cannot be found.
  auto exact_intervals = [&](int c) {
    std::vector<double>& ev = events_;
    ev.clear();
    double e[3];
    if (!pencil_events(ps_.prims, c, pen, e, ev)) return false;
    // The line cut at the events inside it; each part decided at its
    // middle: the pencil's line there meets the quadric (e >= 0) and, for
    // a cone, the surface between its rims. The line meets the body only
    // between the origin and the light (between_origins_and_light).
    ev.erase(std::remove_if(ev.begin(), ev.end(),
                            [&](double a) { return !(a > l.a_first && a < l.a_last); }),
             ev.end());
    std::sort(ev.begin(), ev.end());
    ev.push_back(l.a_last);
    const PrimRef& ref = ps_.prims.prims[c];
    bool open = false;
    double start = 0, x = l.a_first;
    for (const double y : ev) {
      if (!(y > x)) continue;
      const double a = 0.5 * (x + y);
      bool in = (e[0] * a + e[1]) * a + e[2] >= 0;
      if (in && ref.kind == PrimKind::kCone) {
        const ConePrim& cone = ps_.prims.cones[ref.index];
        ++stats_.tests_ray_object;
        in = intersect_cone(cone.c, cone.axis, Ray{pen.point, pen.p0 + a * pen.p1}, -kInf, kInf,
                            nullptr) > 0;
      }
      // Shadowed parts are merged into intervals.
      if (in && !open) start = x;
      if (!in && open) out.push_back(Interval{c, true, start, x, false});
      open = in;
      x = y;
    }
    if (open) out.push_back(Interval{c, true, start, l.a_last, false});
    return true;
  };
  // One candidate occluder c: the interval of each of its volumes that
  // `each_volume(fn)` hands to fn (all of them, or a group's list).
  auto occluder_volumes = [&](int c, auto&& each_volume) {
    const LightVolumes::Occluder& oc = lv.occluders[c];
    if (oc.bound >= 0) {
      ++stats_.tests_shadow_volume;
      if (!meets_span(lv.set, oc.bound, l, lv.slack)) return;
    }
    if (!oc.decides && is_opaque(ps_, c) &&
        between_origins_and_light(ps_.prims, c, n, f.offset, sigma, ps_.eps, h_light, lv.slack) &&
        exact_intervals(c)) {
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
  };
  auto occluder = [&](int c) {
    const LightVolumes::Occluder& oc = lv.occluders[c];
    occluder_volumes(c, [&](auto&& fn) {
      for (int v = oc.first; v < oc.first + oc.count; ++v) fn(v);
    });
  };
  // Opaque intervals first: a pixel in one needs no exact test.
  auto opaque_first = [&] {
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
  };
  if (group_rows_ > 0) {
    const GroupSlot& g = group_candidates(j);
    const std::vector<int>& cands = g.candidates[j];
    const std::vector<int>& vf = g.vol_first[j];
    const int* vols = g.volumes[j].data();
    for (size_t k = 0; k < cands.size(); ++k) {
      occluder_volumes(cands[k], [&](auto&& fn) {
        for (int q = vf[k]; q < vf[k + 1]; ++q) fn(vols[q]);
      });
    }
    opaque_first();
    return;
  }
  if (!ps_.volumes->search) {
    // Configurations II and III: no boxes and no front/back relations, so
    // the span meets every occluder's volume.
    for (int c = 0; c < static_cast<int>(lv.occluders.size()); ++c) occluder(c);
    opaque_first();
    return;
  }
  const int* cb = lv.candidates.data() + lv.candidate_first[f.prim];
  const int* ce = lv.candidates.data() + lv.candidate_first[f.prim + 1];
  if (ce - cb <= kWalkAbove) {
    for (const int* c = cb; c != ce; ++c) occluder(*c);
    opaque_first();
    return;
  }
  // A long list (a floor under many objects): walk the hierarchy with the
  // boxes' volumes against the span, then narrow by the list (paper §4.1).
  int stack[128];
  int sp = 0;
  stack[sp++] = 0;
  while (sp) {
    const int ni = stack[--sp];
    ++stats_.tests_shadow_volume;
    if (!meets_span(lv.set, lv.node_volume[ni], l, kNodeSlack * lv.slack)) continue;
    const BvhNode& node = ps_.bvh.nodes[ni];
    if (node.count == 0) {
      stack[sp++] = node.first;
      stack[sp++] = ni + 1;
      continue;
    }
    for (int k = node.first; k < node.first + node.count; ++k) {
      const int a = ps_.bvh.order[k];
      if (std::binary_search(cb, ce, a)) occluder(a);
    }
  }
  opaque_first();
}

std::optional<Color> SpanShadows::transmittance(const Vec3& p, const Vec3& origin, int light) {
  if (light >= lights_) return std::nullopt;
  if (!s_->done[light]) compute_light(light);
  const ScanFace& f = ps_.scan->faces[face_];
  // The intervals hold for origins on the light's side of the face; a
  // light almost in the face's plane may put a pixel's origin on the other.
  if ((glm::dot(origin - p, f.normal) > 0) != static_cast<bool>(s_->side[light])) {
    if (!ps_.volumes->search) return std::nullopt;  // a shadow ray decides
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
