#include "common/scan/sub_line.h"

#include <algorithm>
#include <cmath>

#include "common/geometry/pencil.h"
#include "common/scan/multiscan.h"

namespace locus {
namespace {

// The sub-scanlines of this many pixel rows share their spans' candidate
// occluders (SpanShadows::set_group_rows; docs/multiscan.md).
constexpr double kShadowGroupRows = 8.0;

// silhouette_guess's probes lie this far (pixels) on either side of the
// outline it checks: the change is then located to kBisectTolerance, as
// bisection would.
constexpr double kSilhouetteCheck = 0.5 * kBisectTolerance;

}  // namespace

// The builder's private steps are used in this file only and are defined
// `inline`, so that the compiler inlines them into build() as it did when
// they were written in the class (without it, rings at 128², --aa 4 took
// 0.3% more instructions).

template <class Fn>
void SubLineBuilder::for_pixels(double x0, double x1, Fn&& fn) {
  double a = x0;
  while (a < x1) {
    const double b = std::min(x1, std::floor(a) + 1.0);
    fn(a, b);
    a = b;
  }
}

SubLineBuilder::SubLineBuilder(const PreparedScene& ps, Tracer& tracer, Stats& stats, int aa,
                               int j0, int j1, CostMeter& meter)
    : ps_(ps),
      scan_(*ps.scan),
      cam_(ps.camera),
      tracer_(tracer),
      stats_(stats),
      meter_(meter),
      eye_(*ps.scan, ps.camera.width, j0, j1),
      samples_(ps, tracer, eye_, stats, aa, j0, j1),
      sample_spacing_(1.0 / std::max(1, aa)) {}

void SubLineBuilder::build(double y, int row, SubLine& line) {
  line.y = y;
  line.pieces.clear();
  line.spans = line.traced_spans = 0;
  out_ = &line.pieces;
  start_line(y, row);
  meter_.charge_run(0, cam_.width);  // the line's visible segments and shadows' set-up
  add_pieces(line);
  index_pixels(line);
}

inline void SubLineBuilder::start_line(double y, int row) {
  y_ = y;
  samples_.set_line(y);
  if (scan_.trace_everything) {
    segs_.assign(1, VisibleSegment{0.0, static_cast<double>(cam_.width), -2});
  } else {
    visible_segments(scan_, cam_, y, scan_.cover[row], vis_, segs_);
  }
  eye_.set_line(vis_.ivs);
  if (ps_.volumes) {
    if (!shadows_) {
      shadows_.emplace(ps_, y, stats_);
      shadows_->set_group_rows(kShadowGroupRows);
    }
    shadows_->set_line(y);
  }
}

inline void SubLineBuilder::add_pieces(SubLine& line) {
  const std::vector<VisibleSegment>& segs = segs_;
  std::optional<SpanShadows>& shadows = shadows_;
  for (size_t si = 0; si < segs.size(); ++si) {
    const VisibleSegment& s = segs[si];
    ++line.spans;
    if (s.face == -1) {
      for_pixels(s.x0, s.x1, [&](double a, double b) {
        Piece p;
        p.x0 = a;
        p.x1 = b;
        out_->push_back(p);
      });
      continue;
    }
    if (is_curved(s)) {
      // Inside curved bodies' bounding polyhedra (paper §3.2, §3.3): the
      // run of neighbouring such spans is sampled as one.
      ++line.traced_spans;
      double x1 = s.x1;
      while (si + 1 < segs.size() && is_curved(segs[si + 1])) x1 = segs[++si].x1;
      curved(s.x0, x1);
      continue;
    }
    const ScanFace& f = scan_.faces[s.face];
    const Material& m = ps_.scene.materials[f.material];
    if (shadows) shadows->begin_span(s.face, s.x0, s.x1);
    meter_.charge_run(s.x0, s.x1);
    if (m.ks > 0 || m.t > 0) {
      ++line.traced_spans;
      mirror(s, shadows ? &*shadows : nullptr);
    } else if (shadows) {
      figures(s, *shadows);
    } else {
      figures_by_rays(s);  // no volumes: shadow rays find the states
    }
  }
}

inline void SubLineBuilder::index_pixels(SubLine& line) const {
  line.first.assign(cam_.width + 1, static_cast<int>(line.pieces.size()));
  for (int k = static_cast<int>(line.pieces.size()) - 1; k >= 0; --k) {
    const int i = clamped_floor(line.pieces[k].x0, 0, cam_.width - 1);
    line.first[i] = k;
  }
  for (int i = cam_.width - 1; i >= 0; --i)
    line.first[i] = std::min(line.first[i], line.first[i + 1]);
}

inline std::pair<int, Color> SubLineBuilder::sample(double x) {
  ++stats_.rays_eye;
  const Ray ray = eye_ray(x);
  const auto hit = eye_.nearest_in_square(tracer_, ray, cam_.hither, x, y_);
  if (!hit) return {-1, ps_.scene.background};
  return {hit->prim, tracer_.shade(ray, *hit, 1, 1.0, nullptr)};
}

inline int SubLineBuilder::first_hit(double x) {
  ++stats_.rays_eye;
  const auto hit = eye_.nearest_on_line(tracer_, eye_ray(x), cam_.hither, x);
  return hit ? hit->prim : -1;
}

// Where two samples at xl < xr found keys kl != kr, bisection finds to
// kBisectTolerance where the key changes; `key_at(x)` gives the key at x.
// Where it is a third key (a surface or shadow between the two samples),
// both halves are searched in turn, so every change found is recorded.
// First, `guess(xl, kl, xr, kr, &x)` may find the change at once
// (silhouette_guess). Appends the changes to `out` in x order: (x, key
// from x).
template <class Key, class KeyAt, class Guess>
void SubLineBuilder::changes(double xl, Key kl, double xr, const Key& kr, KeyAt& key_at,
                             Guess& guess, std::vector<std::pair<double, Key>>& out) {
  if (double x; guess(xl, kl, xr, kr, &x)) {
    out.emplace_back(x, kr);
    return;
  }
  while (xr - xl > kBisectTolerance) {
    const double xm = 0.5 * (xl + xr);
    Key km = key_at(xm);
    if (km == kl) {
      xl = xm;
    } else if (km == kr) {
      xr = xm;
    } else {
      changes(xl, kl, xm, km, key_at, guess, out);
      kl = std::move(km);
      xl = xm;
    }
  }
  out.emplace_back(0.5 * (xl + xr), kr);
}

// Refines the pieces [begin, end) of *out_, whose keys (what the sample
// at each piece's midpoint found) are `keys`: where neighbours differ,
// and between each end of the run and the piece next to it (`key_at(x)`
// there), bisection finds where the key changes (`changes`), and each
// piece is cut there, its parts given their keys (`fill(part, key)`).
// This is the paper's convergence search (§3.3); a feature that begins
// and ends between two samples is seen only where the bisection's probes
// meet it (docs/multiscan.md).
template <class Key, class KeyAt, class Fill, class Guess>
void SubLineBuilder::refine(size_t begin, const std::vector<Key>& keys, KeyAt&& key_at, Fill&& fill,
                            Guess&& guess, std::vector<std::pair<double, Key>>& found) {
  const size_t n = keys.size();
  if (n == 0) return;
  // The pieces are read in place; copied only if they are to be cut.
  const Piece* run = out_->data() + begin;
  auto mid = [](const Piece& p) { return 0.5 * (p.x0 + p.x1); };
  constexpr double kEnd = 1e-6;  // end probes, just inside the run
  found.clear();
  Key start = keys[0];
  if (const Piece& p = run[0]; mid(p) - p.x0 > 2 * kEnd) {
    Key kl = key_at(p.x0 + kEnd);
    if (!(kl == keys[0])) {
      changes(p.x0 + kEnd, kl, mid(p), keys[0], key_at, guess, found);
      start = std::move(kl);
    }
  }
  for (size_t k = 1; k < n; ++k) {
    if (!(keys[k - 1] == keys[k])) {
      changes(mid(run[k - 1]), keys[k - 1], mid(run[k]), keys[k], key_at, guess, found);
    }
  }
  if (const Piece& p = run[n - 1]; p.x1 - mid(p) > 2 * kEnd) {
    const Key kr = key_at(p.x1 - kEnd);
    if (!(kr == keys[n - 1])) changes(mid(p), keys[n - 1], p.x1 - kEnd, kr, key_at, guess, found);
  }
  if (found.empty()) return;
  run_.assign(run, run + n);
  out_->resize(begin);
  size_t t = 0;
  const Key* key = &start;
  auto part = [&](double x0, double x1, const Piece& like) {
    Piece q = like;
    q.x0 = x0;
    q.x1 = x1;
    fill(q, *key);
    out_->push_back(q);
  };
  for (const Piece& p : run_) {
    double a = p.x0;
    for (; t < found.size() && found[t].first < p.x1; ++t) {
      if (found[t].first > a) {
        part(a, found[t].first, p);
        a = found[t].first;
      }
      key = &found[t].second;
    }
    part(a, p.x1, p);
  }
}

// Where the first surface hit changes from kl (at xl) to kr (at xr) and
// one of them is a sphere or cone, the change is likely that body's
// outline on this sub-scanline: where the eye's rays touch its quadric
// or pass through a rim (common/geometry/pencil.h). Each such x in (xl, xr) is
// tried with a probe on either side, kSilhouetteCheck away (or the
// sample at xl or xr, if nearer); the first whose probes find kl and kr
// is the change, found in two probes where bisection takes six. A change
// elsewhere (one body entering another, or a third surface between) is
// left to bisection.
inline bool SubLineBuilder::silhouette_guess(double xl, int kl, double xr, int kr, double* x) {
  const double scale = cam_.tan_half * cam_.aspect;  // a = (2 x / width - 1) scale
  const Pencil eye{cam_.from, cam_.w + (1.0 - 2.0 * y_ / cam_.height) * cam_.tan_half * cam_.v,
                   cam_.u};
  guesses_.clear();
  for (const int k : {kl, kr}) {
    double e[3];
    if (k >= 0 && plain_quadric(ps_.prims, k)) pencil_events(ps_.prims, k, eye, e, guesses_);
  }
  for (const double a : guesses_) {
    const double g = 0.5 * cam_.width * (1.0 + a / scale);
    if (!(g > xl && g < xr)) continue;
    // A probe that would fall beyond xl or xr is the sample there.
    const double gl = g - kSilhouetteCheck, gr = g + kSilhouetteCheck;
    if ((gl <= xl || first_hit(gl) == kl) && (gr >= xr || first_hit(gr) == kr)) {
      *x = g;
      return true;
    }
  }
  return false;
}

// A run of curved bodies' spans: the first surface hit at one point per
// pixel, refined where it changes (the true silhouettes); then each
// piece's radiance (traced_colours).
inline void SubLineBuilder::curved(double x0, double x1) {
  const size_t begin = out_->size();
  std::vector<int>& ids = ids_;
  ids.clear();
  for_pixels(x0, x1, [&](double a, double b) {
    Piece p;
    p.x0 = a;
    p.x1 = b;
    p.kind = Piece::kTraced;
    p.hit = first_hit(0.5 * (a + b));
    out_->push_back(p);
    ids.push_back(p.hit);
    meter_.charge(a);
  });
  refine(
      begin, ids, [&](double x) { return first_hit(x); }, [](Piece& q, int id) { q.hit = id; },
      [&](double xl, int kl, double xr, int kr, double* x) {
        return silhouette_guess(xl, kl, xr, kr, x);
      },
      found_ids_);
  meter_.charge_run(x0, x1);
  auto direct = [&](double x) { return sample(x).second; };
  for (size_t k = begin; k < out_->size(); ++k) {
    Piece& p = (*out_)[k];
    if (p.hit < 0) {
      p.traced.colour = p.traced.colour_up = ps_.scene.background;
    } else {
      traced_colours(p, direct);
      meter_.charge(p.x0);
    }
  }
}

inline void SubLineBuilder::traced_colours(Piece& p, FunctionRef<Color(double)> direct) {
  const PieceColours c = samples_.colours(p.x0, p.x1, p.hit, direct);
  p.traced.colour = c.colour;
  p.traced.colour_up = c.colour_up;
}

// A mirror's or glass's flat face: the visible face is known, so each
// sample is a ray-plane intersection (paper §3.2), then local ray tracing.
inline void SubLineBuilder::mirror(const VisibleSegment& s, SpanShadows* shadows) {
  const ScanFace& f = scan_.faces[s.face];
  auto colour_at = [&](double x) {
    const Ray ray = eye_ray(x);
    ++stats_.tests_ray_object;
    const auto hit = hit_on_face(ps_, f, ray);
    if (!hit) return sample(x).second;
    if (shadows) shadows->set_x(x);
    return tracer_.shade(ray, SurfaceHit{hit->t, f.prim, *hit}, 1, 1.0, nullptr, shadows);
  };
  for_pixels(s.x0, s.x1, [&](double a, double b) {
    Piece p;
    p.x0 = a;
    p.x1 = b;
    p.kind = Piece::kTraced;
    p.hit = f.prim;
    traced_colours(p, colour_at);
    out_->push_back(p);
    meter_.charge(a);
  });
}

// A diffuse face's span: cut where shadow intervals begin and end (paper
// §3.2 step 2) and at pixel edges. Inside the volume of a curved or
// transparent occluder the state of the lights comes from exact tests at
// the pieces' midpoints, refined where it changes.
inline void SubLineBuilder::figures(const VisibleSegment& s, SpanShadows& shadows) {
  cuts_.assign({s.x0, s.x1});
  shadows.breakpoints(cuts_);
  std::sort(cuts_.begin(), cuts_.end());
  cuts_.erase(std::unique(cuts_.begin(), cuts_.end()), cuts_.end());
  std::vector<LightStates>& keys = keys_;
  keys.clear();
  size_t run_begin = out_->size();
  auto end_run = [&] {
    refine(
        run_begin, keys, [&](double x) { return shadows.states(x); },
        [](Piece& q, const LightStates& st) { q.lights = st; },
        [](double, const LightStates&, double, const LightStates&, double*) { return false; },
        found_states_);
    keys.clear();
    run_begin = out_->size();
  };
  Piece p;
  p.kind = Piece::kFigure;
  p.face = s.face;
  for (size_t k = 0; k + 1 < cuts_.size(); ++k) {
    const double a = cuts_[k], b = cuts_[k + 1];
    if (!(b > a) || a < s.x0 || b > s.x1) continue;
    // Interval ends are breakpoints, so an interval over the segment
    // covers all of it; one that only touches an end (through rounding
    // of x <-> a) is not counted.
    constexpr double kTouch = 1e-9;  // pixels
    const bool unsure =
        b - a > 2 * kTouch ? shadows.uncertain(a + kTouch, b - kTouch) : shadows.uncertain(a, b);
    if (!unsure) {
      // Between two interval ends, with only opaque volumes over it: one
      // state for the whole segment, cut at pixel edges.
      end_run();
      p.lights = shadows.states(0.5 * (a + b));
      for_pixels(a, b, [&](double x0, double x1) {
        p.x0 = x0;
        p.x1 = x1;
        out_->push_back(p);
      });
      run_begin = out_->size();
      continue;
    }
    // Inside a curved or transparent occluder's volume: exact tests at
    // each pixel's piece, refined where they change.
    for_pixels(a, b, [&](double x0, double x1) {
      p.x0 = x0;
      p.x1 = x1;
      p.lights = shadows.states(0.5 * (x0 + x1));
      out_->push_back(p);
      keys.push_back(p.lights);
    });
  }
  end_run();
  meter_.charge_run(s.x0, s.x1);
}

// Without volumes (shadows by rays, docs/renderer.md): the span is cut into
// figures as figures() cuts it inside an occluder's volume, each pixel's
// piece keyed by the state of the lights at its midpoint and refined where
// neighbours differ (paper §3.3's convergence search), the keys found by
// shadow rays instead of intervals. A figure is then shaded once per pixel
// (multiscan.cpp), not once per sample.
inline void SubLineBuilder::figures_by_rays(const VisibleSegment& s) {
  const ScanFace& f = scan_.faces[s.face];
  Piece p;
  p.kind = Piece::kFigure;
  p.face = s.face;
  // The span's middle point tells which lights light none of the face, and
  // a narrow span's state is taken there too: found once for both.
  const Ray mid_eye = eye_ray(0.5 * (s.x0 + s.x1));
  const Vec3 mid = point_on(f, mid_eye);
  const uint64_t unlit = unlit_lights(f, mid_eye, mid);
  auto key_at = [&](double x) { return ray_states(f, point_on(f, eye_ray(x)), unlit); };
  // A span narrower than the sub-scanlines' spacing h = 1/N pixel is
  // sampled once, at its middle, as supersampling at that spacing would
  // sample it: one shadow ray per light, no end probes, no bisection. A
  // state that changes inside it is an error of less than h/2 along the
  // line, what the sub-scanlines' spacing makes across them. Sub-pixel
  // geometry (SPD tetra level 9, 512², --aa 4: 41% of the spans) then costs
  // one shadow ray per light instead of three; the error against a dense
  // reference is unchanged to 0.3% (docs/renderer.md, "Shadows by rays").
  // (Spans up to 2h sampled at two points lost the end probes' accuracy
  // where faces shadow their neighbours: +9% error on a grid of sub-pixel
  // faces.)
  if (s.x1 - s.x0 < sample_spacing_) {
    p.lights = ray_states(f, mid, unlit);
    for_pixels(s.x0, s.x1, [&](double a, double b) {
      p.x0 = a;
      p.x1 = b;
      out_->push_back(p);
      meter_.charge(a);
    });
    meter_.charge_run(s.x0, s.x1);
    return;
  }
  std::vector<LightStates>& keys = keys_;
  keys.clear();
  const size_t begin = out_->size();
  for_pixels(s.x0, s.x1, [&](double a, double b) {
    p.x0 = a;
    p.x1 = b;
    p.lights = key_at(0.5 * (a + b));
    out_->push_back(p);
    keys.push_back(p.lights);
    meter_.charge(a);
  });
  refine(
      begin, keys, key_at, [](Piece& q, const LightStates& st) { q.lights = st; },
      [](double, const LightStates&, double, const LightStates&, double*) { return false; },
      found_states_);
  meter_.charge_run(s.x0, s.x1);
}

// The first 64 lights that light none of face f: a light on the far side
// of a flat face from the eye (Tracer::shade skips it before asking for its
// shadow), or every light where the face's material has no diffuse or
// specular term. Which side of the face's plane the eye and a light lie on
// is the same at every point of the face, so one point p of it tells.
inline uint64_t SubLineBuilder::unlit_lights(const ScanFace& f, const Ray& eye,
                                             const Vec3& p) const {
  const int lights = static_cast<int>(std::min<size_t>(ps_.scene.lights.size(), 64));
  const uint64_t all = lights == 64 ? ~uint64_t{0} : (uint64_t{1} << lights) - 1;
  const Material& m = ps_.scene.materials[f.material];
  if (m.kd == 0 && m.ks == 0) return all;
  if (f.smooth) return 0;  // the shading normal varies
  // The side the eye sees (Tracer::shade's n).
  const Vec3 seen = glm::dot(f.normal, eye.dir) > 0 ? -f.normal : f.normal;
  uint64_t unlit = 0;
  for (int j = 0; j < lights; ++j) {
    if (glm::dot(seen, ps_.scene.lights[j].position - p) <= 0) unlit |= uint64_t{1} << j;
  }
  return unlit;
}

// The state of the first 64 lights at point p of face f (seen on this
// sub-scanline): a shadow ray to each, as Tracer::transmittance casts it, but
// to the `unlit` ones (unlit_lights), which count as blocked, the same on
// the whole face, so they cut no figure.
inline LightStates SubLineBuilder::ray_states(const ScanFace& f, const Vec3& p, uint64_t unlit) {
  LightStates st;
  st.opaque = unlit;
  const int lights = static_cast<int>(std::min<size_t>(ps_.scene.lights.size(), 64));
  for (int j = 0; j < lights; ++j) {
    if (unlit >> j & 1) continue;
    const Vec3 origin = tracer_.shadow_origin(p, f.normal, j);
    const Ray seg{origin, ps_.scene.lights[j].position - origin};
    crossings_.clear();
    const bool opaque = tracer_.shadow_crossings(seg, j, crossings_, f.prim);
    add_light_state(st, j, opaque, ps_.scene, seg, crossings_);
  }
  return st;
}

}  // namespace locus
