// SpanShadows: the shadows of scanline spans (paper §3.2 step 2), for point
// sampling and multi-scanning. The volumes come from shadow_volume.cpp.
#include "common/span_shadows.h"

#include <algorithm>
#include <optional>

#include "common/prepared.h"
#include "common/scanline.h"

namespace locus {
namespace {

// A span tests a candidate list this long directly; a longer one through
// the hierarchy.
constexpr int kWalkAbove = 8;

}  // namespace

SpanShadows::SpanShadows(const PreparedScene& ps, double y, Stats& stats)
    : ps_(ps), stats_(stats), lights_(static_cast<int>(ps.scene.lights.size())) {
  const CameraFrame& cam = ps.camera;
  a_line_lo_ = image_a(0.0);
  a_line_hi_ = image_a(cam.width);
  set_line(y);
}

void SpanShadows::set_line(double y) {
  const CameraFrame& cam = ps_.camera;
  b_ = (1.0 - 2.0 * y / cam.height) * cam.tan_half;
  face_ = -1;
  used_ = 0;
  s_ = nullptr;
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
  for (int k = 0; k < used_; ++k) {
    if (slots_[k].face == face) {
      s_ = &slots_[k];
      return;
    }
  }
  if (used_ == static_cast<int>(slots_.size())) slots_.emplace_back();
  s_ = &slots_[used_++];
  s_->face = face;
  s_->done.assign(lights_, 0);
  s_->side.assign(lights_, 0);
  s_->iv.resize(lights_);
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

bool SpanShadows::uncertain(double x0, double x1) {
  const double a0 = image_a(x0), a1 = image_a(x1);
  for (int j = 0; j < lights_; ++j) {
    if (!s_->done[j]) compute_light(j);
    for (const Interval& iv : s_->iv[j]) {
      if (iv.decides) continue;
      // Where a non-deciding volume holds the points, an exact test does.
      if (iv.outside ? (a0 < iv.lo || a1 > iv.hi) : (iv.lo < a1 && a0 < iv.hi)) return true;
    }
  }
  return false;
}

LightStates SpanShadows::states(double x) {
  LightStates st;
  const double a = image_a(x);
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
    for (const Interval& iv : s_->iv[j]) {  // opaque intervals first
      if (((iv.lo <= a && a <= iv.hi) == iv.outside)) continue;
      if (iv.decides) {
        opaque = true;
        break;
      }
      if (iv.prim == tested) continue;
      tested = iv.prim;
      if (!p) {
        const Vec3 d = cam.w + b_ * cam.v + a * cam.u;
        p = cam.from + ((f.offset - glm::dot(f.normal, cam.from)) / glm::dot(f.normal, d)) * d;
      }
      const Vec3 origin = *p + (s_->side[j] ? ps_.eps : -ps_.eps) * f.normal;
      seg = Ray{origin, ps_.volumes->lights[j].position - origin};
      if (exact_test(ps_, iv.prim, seg, crossings, stats_)) {
        opaque = true;
        break;
      }
    }
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

}  // namespace

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
  // One candidate occluder: the interval of each of its volumes.
  auto occluder = [&](int c) {
    const LightVolumes::Occluder& oc = lv.occluders[c];
    if (oc.bound >= 0) {
      ++stats_.tests_shadow_volume;
      if (!meets_span(lv.set, oc.bound, l, lv.slack)) return;
    }
    const double slack = oc.decides ? 0.0 : lv.slack;
    for (int v = oc.first; v < oc.first + oc.count; ++v) {
      ++stats_.tests_shadow_volume;
      const ShadowVolume& vol = lv.set.volumes[v];
      if (vol.kind == VolumeKind::kEverywhere) {
        out.push_back(Interval{c, oc.decides, l.a_first, l.a_last, false});
        continue;
      }
      double lo, hi;
      inside_range(lv.set, vol, l, slack, vol.kind == VolumeKind::kConvex, &lo, &hi);
      if (vol.kind == VolumeKind::kConvex) {
        if (lo > hi || lo > l.a_last || hi < l.a_first) continue;
        out.push_back(Interval{c, oc.decides, lo, hi, false});
      } else {
        // kOutside: shadow outside [lo, hi].
        if (lo <= l.a_first && hi >= l.a_last) continue;
        out.push_back(Interval{c, oc.decides, lo, hi, true});
      }
    }
  };
  // Opaque intervals first: a pixel in one needs no exact test.
  auto opaque_first = [&] {
    std::stable_partition(out.begin(), out.end(), [](const Interval& i) { return i.decides; });
  };
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
    if (!meets_span(lv.set, lv.node_volume[ni], l, lv.slack)) continue;
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
