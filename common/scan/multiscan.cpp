#include "common/scan/multiscan.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "common/geometry/pencil.h"
#include "common/scan/eye_candidates.h"
#include "common/scan/scanline.h"
#include "common/scan/span_shadows.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace {

// Adaptive refinement inside ray-traced spans (issue #6 item 3;
// SubLineBuilder::traced_colour): a traced piece is interpolated from its
// pixel's corner samples where they (and, for N >= 8, the pixel's interior
// grid) see one material and differ by at most kContrast (largest channel,
// linear radiance), blended out as the spread grows to twice that.
// Otherwise it takes the mean radiance of the samples of a stratified grid
// inside the pixel (2 max(1, N / 4) squared) that see its material.
constexpr double kContrast = 0.05;

// A silhouette's pixel (its corners see different materials; N < 8)
// estimates each material's radiance from the samples that see it: three
// inside (weight 1 each) and the four corners (this weight each). Measured
// against --spp 16 on rings, balls, (b) and (d) at 256²: 1/2 gives lower
// RMSE than 1/8, 1/4, 3/4 or 1 (docs/multiscan.md).
constexpr double kSilhouetteCorner = 0.5;

// The sub-scanlines of this many pixel rows share their spans' candidate
// occluders (SpanShadows::set_group_rows; docs/multiscan.md).
constexpr double kShadowGroupRows = 8.0;

// silhouette_guess's probes lie this far (pixels) on either side of the
// outline it checks: the change is then located to kBisectTolerance, as
// bisection would.
constexpr double kSilhouetteCheck = 0.5 * kBisectTolerance;

// A visible figure's piece of one sub-scanline, inside one pixel.
struct Piece {
  enum Kind : uint8_t { kBackground, kTraced, kFigure };
  double x0 = 0, x1 = 0;
  Kind kind = kBackground;
  int face = -1;       // kFigure: index into ScanScene::faces
  int hit = -1;        // kTraced: the first surface the sample met (-1: none)
  // kTraced: the piece's radiance for the pixel row below the sub-scanline
  // (or holding it), and on a row boundary also for the row above (each
  // row's pixels estimate it from their own samples; traced_colour).
  Color colour{0.0}, colour_up{0.0};
  LightStates lights;  // kFigure: the state of the lights on the piece
};

// One sub-scanline: its pieces in x order, and pixel i's pieces
// [first[i], first[i + 1]).
struct SubLine {
  double y = 0;
  std::vector<Piece> pieces;
  std::vector<int> first;
  int spans = 0, traced_spans = 0;
};

// Shadows known per figure: the state of each light on it.
class FigureShadows : public KnownShadows {
 public:
  explicit FigureShadows(const LightStates& s) : s_(s) {}
  std::optional<Color> transmittance(const Vec3&, const Vec3&, int light) override {
    if (light >= 64) return std::nullopt;
    const uint64_t bit = uint64_t{1} << light;
    if (s_.opaque & bit) return Color(0.0);
    if (s_.partial & bit) return std::nullopt;  // eqs. (2), (3) at the point itself
    return Color(1.0);
  }

 private:
  LightStates s_;
};

class SubLineBuilder {
 public:
  // Lattice rows [j0, j1] (pixel corners y = j0..j1) may be used.
  SubLineBuilder(const PreparedScene& ps, Tracer& tracer, Stats& stats, int aa, int j0, int j1)
      : ps_(ps), scan_(*ps.scan), cam_(ps.camera), tracer_(tracer), stats_(stats),
        j0_(j0),
        lattice_(static_cast<size_t>(ps.camera.width) + 1),
        grid_(std::max(1, aa / 4)),
        j1_(j1),
        interior_(static_cast<size_t>(ps.camera.width) * grid_ * grid_),
        fine_(static_cast<size_t>(ps.camera.width) * 4 * grid_ * grid_),
        eye_(*ps.scan, ps.camera.width, j0, j1) {}

  // Fills `line` (its allocations are reused) with sub-scanline y of `row`.
  void build(double y, int row, SubLine& line) {
    line.y = y;
    line.pieces.clear();
    line.spans = line.traced_spans = 0;
    y_ = y;
    // The band's pixel rows whose pixels this sub-scanline's traced pieces
    // are estimated for (-1: none): the row that holds it, and on a row
    // boundary the row above, which it closes.
    const int below = static_cast<int>(std::floor(y));
    row_down_ = below >= j0_ && below < j1_ - 1 && below < cam_.height ? below : -1;
    row_up_ = y == below && below - 1 >= j0_ && below - 1 < j1_ - 1 ? below - 1 : -1;
    out_ = &line.pieces;
    std::vector<VisibleSegment>& segs = segs_;
    if (scan_.trace_everything) {
      segs.assign(1, VisibleSegment{0.0, static_cast<double>(cam_.width), -2});
    } else {
      visible_segments(scan_, cam_, y, scan_.cover[row], vis_, segs);
    }
    eye_.set_line(vis_.ivs);
    std::optional<SpanShadows>& shadows = shadows_;
    if (ps_.volumes) {
      if (!shadows) {
        shadows.emplace(ps_, y, stats_);
        shadows->set_group_rows(kShadowGroupRows);
        shadows->set_line(y);
      } else {
        shadows->set_line(y);
      }
    }
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
      const Material& m = ps_.scene.materials[ps_.scene.objects[ps_.prims.prims[f.prim].object].material];
      if (shadows) shadows->begin_span(s.face, s.x0, s.x1);
      if (m.ks > 0 || m.t > 0) {
        ++line.traced_spans;
        mirror(s, shadows ? &*shadows : nullptr);
      } else if (shadows) {
        figures(s, *shadows);
      } else {
        mirror(s, nullptr);  // no volumes: sampled like a mirror's span
      }
    }
    // Pixel i's pieces.
    line.first.assign(cam_.width + 1, static_cast<int>(line.pieces.size()));
    for (int k = static_cast<int>(line.pieces.size()) - 1; k >= 0; --k) {
      const int i = std::clamp(static_cast<int>(std::floor(line.pieces[k].x0)), 0, cam_.width - 1);
      line.first[i] = k;
    }
    for (int i = cam_.width - 1; i >= 0; --i) line.first[i] = std::min(line.first[i], line.first[i + 1]);
  }

 private:
  // Calls fn(a, b) for the parts of [x0, x1) in each pixel, left to right.
  template <class Fn>
  void for_pixels(double x0, double x1, Fn&& fn) {
    double a = x0;
    while (a < x1) {
      const double b = std::min(x1, std::floor(a) + 1.0);
      fn(a, b);
      a = b;
    }
  }

  // Sampled with bisection: curved bodies' spans, and faces cut by hither.
  bool is_curved(const VisibleSegment& s) const {
    return s.face == -2 || (s.face >= 0 && (scan_.faces[s.face].curved || scan_.faces[s.face].near_hither));
  }

  Ray eye_ray(double x) const { return Ray{cam_.from, cam_.direction(x, y_)}; }

  // The first surface along the eye ray at x, and its radiance.
  std::pair<int, Color> sample(double x) {
    ++stats_.rays_eye;
    const Ray ray = eye_ray(x);
    const auto hit = eye_nearest(ray, x, y_);
    if (!hit) return {-1, ps_.scene.background};
    return {hit->prim, tracer_.shade(ray, *hit, 1, 1.0, nullptr)};
  }
  int first_hit(double x) {
    ++stats_.rays_eye;
    const auto hit = eye_nearest(eye_ray(x), x, y_, true);
    return hit ? hit->prim : -1;
  }
  // The nearest surface along the eye ray through image point (x, y),
  // searched among the primitives whose outlines hold the point
  // (EyeCandidates): those of the current sub-scanline's intervals if
  // `on_line` (y is this sub-scanline), else those meeting its pixel square.
  std::optional<SurfaceHit> eye_nearest(const Ray& ray, double x, double y, bool on_line = false) {
    if (!eye_.active()) return tracer_.nearest(ray, cam_.hither, kInf);
    return tracer_.nearest_among(ray, cam_.hither, kInf,
                                 on_line ? eye_.on_line(x) : eye_.in_square(x, y));
  }

  // Where two samples at xl < xr found keys kl != kr, bisection finds to
  // kBisectTolerance where the key changes; `key_at(x)` gives the key at x.
  // Where it is a third key (a surface or shadow between the two samples),
  // both halves are searched in turn, so every change found is recorded.
  // First, `guess(xl, kl, xr, kr, &x)` may find the change at once
  // (silhouette_guess). Appends the changes to `out` in x order: (x, key
  // from x).
  template <class Key, class KeyAt, class Guess>
  void changes(double xl, Key kl, double xr, const Key& kr, KeyAt& key_at, Guess& guess,
               std::vector<std::pair<double, Key>>& out) {
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
  void refine(size_t begin, const std::vector<Key>& keys, KeyAt&& key_at, Fill&& fill,
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
  bool silhouette_guess(double xl, int kl, double xr, int kr, double* x) {
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
  // piece's radiance (traced_colour).
  void curved(double x0, double x1) {
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
    });
    refine(
        begin, ids, [&](double x) { return first_hit(x); }, [](Piece& q, int id) { q.hit = id; },
        [&](double xl, int kl, double xr, int kr, double* x) {
          return silhouette_guess(xl, kl, xr, kr, x);
        },
        found_ids_);
    auto direct = [&](double x) { return sample(x).second; };
    for (size_t k = begin; k < out_->size(); ++k) {
      Piece& p = (*out_)[k];
      if (p.hit < 0) {
        p.colour = p.colour_up = ps_.scene.background;
      } else {
        traced_colours(p, direct);
      }
    }
  }

  // A pixel corner's sample: the first surface along the eye ray through
  // image point (i, j), and its radiance.
  struct Corner {
    bool done = false;
    int material = -1;  // of the first surface hit (-1: none)
    Color colour{0.0};
  };
  // The samples of the last few rows, each row `per_row` of them. Rows are
  // asked for in increasing order (a sub-scanline at y uses lattice rows
  // floor(y) - 1 .. floor(y) + 1 and pixel rows floor(y) - 1 and floor(y)),
  // so three slots suffice: a row's slot is cleared when a later row takes
  // it. Memory is a few rows, not the band's (whose first touch cost more
  // than the samples at 512²).
  class RowRing {
   public:
    explicit RowRing(size_t per_row) : per_row_(per_row), data_(kSlots * per_row) {}
    Corner* row(int r) {
      const int slot = r % kSlots;
      Corner* d = data_.data() + static_cast<size_t>(slot) * per_row_;
      if (rows_[slot] != r) {
        std::fill(d, d + per_row_, Corner{});
        rows_[slot] = r;
      }
      return d;
    }

   private:
    static constexpr int kSlots = 3;
    size_t per_row_;
    std::vector<Corner> data_;
    int rows_[kSlots] = {-1, -1, -1};
  };
  // The radiance of a traced piece (p.hit >= 0). The paper samples every
  // piece: one ray per pixel per sub-scanline (§3.3). Where the surface is
  // smooth, that sample is, within kContrast, the bilinear interpolation of
  // the samples at the pixel's corners, which all sub-scanlines of the
  // pixel and of its neighbours share. So if the corners that have a weight
  // here (each traced once, lazily) all see the piece's material and differ
  // by at most kContrast, the piece is interpolated; for N >= 8 the pixel's
  // interior grid must agree too, so that a feature inside the pixel that
  // no corner sees is found as N grows. Otherwise (an edge in the reflected
  // or refracted image, or a silhouette in the pixel: issue #6 item 3's
  // adaptive refinement) the piece's radiance is the mean of the samples
  // of the pixel's fine grid (stratified, traced once for all its
  // sub-scanlines) that see its material: with the exact coverage of each
  // piece, the pixel is then the box filter's integral of each material's
  // radiance, estimated from the samples inside it. Where the corners see
  // different materials at N < 8 (a silhouette crosses the pixel), fewer
  // fine samples do: the pixel's centre and the two fine points on its
  // main diagonal, with its corners (kSilhouetteCorner). A piece whose
  // material none of those samples sees (a sliver thinner than their
  // spacing) is sampled itself (`direct(x)`; docs/multiscan.md).
  template <class Direct>
  void traced_colours(Piece& p, Direct&& direct) {
    // A sliver's own sample is the same ray for both rows: traced once.
    std::optional<Color> own;
    auto once = [&](double x) {
      if (!own) own = direct(x);
      return *own;
    };
    if (row_down_ >= 0) p.colour = traced_colour(p, row_down_, once);
    if (row_up_ >= 0) p.colour_up = traced_colour(p, row_up_, once);
  }
  // The piece's radiance for the pixels of row j (y_ in [j, j + 1]; build()
  // keeps j and j + 1 inside the builder's lattice rows).
  template <class Direct>
  Color traced_colour(const Piece& p, int j, Direct&& direct) {
    const int material = material_of(p.hit);
    const double xm = 0.5 * (p.x0 + p.x1);
    const int i = std::min(static_cast<int>(xm), cam_.width - 1);
    const double fx = xm - i, fy = y_ - j;
    const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    Color lo(kInf), hi(-kInf), acc(0.0);
    bool smooth = true;
    auto agree = [&](const Corner& k) {
      if (k.material != material) return false;
      lo = glm::min(lo, k.colour);
      hi = glm::max(hi, k.colour);
      return true;
    };
    for (int c = 0; c < 4 && smooth; ++c) {
      if (!(w[c] > 0)) continue;
      const Corner& k = corner(i + (c & 1), j + (c >> 1));
      smooth = agree(k);
      acc += w[c] * k.colour;
    }
    if (smooth && grid_ >= 2) {
      const Corner* in = interior(i, j);
      for (int q = 0; q < grid_ * grid_ && smooth; ++q) smooth = agree(in[q]);
    }
    // The interpolation's weight falls from 1 to 0 as the spread goes from
    // kContrast to twice that (no jump where it crosses).
    const double keep = smooth ? std::clamp(2.0 - max_component(hi - lo) / kContrast, 0.0, 1.0) : 0.0;
    if (keep >= 1.0) return acc;
    if (!smooth && grid_ == 1) {
      // A silhouette: the samples of the pixel that see the material.
      Color sum(0.0);
      double weight = 0;
      auto add = [&](const Corner& k, double w) {
        if (k.material != material) return;
        sum += w * k.colour;
        weight += w;
      };
      add(*interior(i, j), 1.0);
      add(fine_point(i, j, 0), 1.0);
      add(fine_point(i, j, 3), 1.0);
      for (int c = 0; c < 4; ++c) add(corner(i + (c & 1), j + (c >> 1)), kSilhouetteCorner);
      return weight > 0 ? sum / weight : direct(xm);
    }
    const int g = 2 * grid_;
    const Corner* in = fine(i, j);
    Color sum(0.0);
    int n = 0;
    for (int q = 0; q < g * g; ++q) {
      if (in[q].material == material) {
        sum += in[q].colour;
        ++n;
      }
    }
    const Color mean = n > 0 ? sum / static_cast<double>(n) : direct(xm);
    return keep > 0 ? keep * acc + (1.0 - keep) * mean : mean;
  }

  // Pixel (i, j)'s interior samples, a grid_ x grid_ grid, and the grid
  // twice as fine, each traced on first use.
  const Corner* interior(int i, int j) { return grid_samples(i, j, grid_, interior_); }
  const Corner* fine(int i, int j) { return grid_samples(i, j, 2 * grid_, fine_); }
  const Corner* grid_samples(int i, int j, int g, RowRing& store) {
    const int n = g * g;
    Corner* in = store.row(j) + static_cast<size_t>(i) * n;
    for (int q = 0; q < n; ++q) grid_point(in[q], i, j, g, q);
    return in;
  }
  // Point q of the fine grid alone (silhouettes).
  const Corner& fine_point(int i, int j, int q) {
    const int g = 2 * grid_;
    Corner& k = fine_.row(j)[static_cast<size_t>(i) * g * g + q];
    grid_point(k, i, j, g, q);
    return k;
  }
  // Traces point q of pixel (i, j)'s g x g grid into k, once.
  void grid_point(Corner& k, int i, int j, int g, int q) {
    if (k.done) return;
    k.done = true;
    ++stats_.rays_eye;
    const double x = i + (q % g + 0.5) / g, y = j + (q / g + 0.5) / g;
    const Ray ray{cam_.from, cam_.direction(x, y)};
    const auto hit = eye_nearest(ray, x, y);
    k.material = hit ? material_of(hit->prim) : -1;
    k.colour = hit ? tracer_.shade(ray, *hit, 1, 1.0, nullptr) : ps_.scene.background;
  }

  int material_of(int prim) const {
    return ps_.scene.objects[ps_.prims.prims[prim].object].material;
  }

  const Corner& corner(int i, int j) {
    Corner& k = lattice_.row(j)[i];
    if (!k.done) {
      k.done = true;
      ++stats_.rays_eye;
      const Ray ray{cam_.from, cam_.direction(i, j)};
      const auto hit = eye_nearest(ray, i, j);
      if (hit) {
        k.material = material_of(hit->prim);
        k.colour = tracer_.shade(ray, *hit, 1, 1.0, nullptr);
      } else {
        k.colour = ps_.scene.background;
      }
    }
    return k;
  }

  // A mirror's or glass's flat face: the visible face is known, so each
  // sample is a ray-plane intersection (paper §3.2), then local ray tracing.
  void mirror(const VisibleSegment& s, SpanShadows* shadows) {
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
    });
  }

  // A diffuse face's span: cut where shadow intervals begin and end (paper
  // §3.2 step 2) and at pixel edges. Inside the volume of a curved or
  // transparent occluder the state of the lights comes from exact tests at
  // the pieces' midpoints, refined where it changes.
  void figures(const VisibleSegment& s, SpanShadows& shadows) {
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
      const bool unsure = b - a > 2 * kTouch ? shadows.uncertain(a + kTouch, b - kTouch)
                                             : shadows.uncertain(a, b);
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
  }

  const PreparedScene& ps_;
  const ScanScene& scan_;
  const CameraFrame& cam_;
  Tracer& tracer_;
  Stats& stats_;
  double y_ = 0;
  std::vector<Piece>* out_ = nullptr;
  std::vector<VisibleSegment> segs_;
  VisibleScratch vis_;
  std::optional<SpanShadows> shadows_;
  std::vector<double> cuts_;
  std::vector<int> ids_;
  std::vector<LightStates> keys_;
  // refine()'s buffers
  std::vector<Piece> run_;
  std::vector<std::pair<double, int>> found_ids_;
  std::vector<std::pair<double, LightStates>> found_states_;
  std::vector<double> guesses_;  // silhouette_guess's
  int j0_;
  int row_down_ = -1, row_up_ = -1;  // build()'s rows
  RowRing lattice_;  // pixel corners, a row of them per lattice row
  int grid_;
  int j1_;
  RowRing interior_, fine_;  // per pixel row
  EyeCandidates eye_;
};

// One figure's share of a pixel, summed over the sub-scanlines.
struct Figure {
  int face;
  LightStates lights;
  double area = 0, cx = 0, cy = 0;
  double rep_w = -1, rep_x = 0, rep_y = 0;  // its largest piece's midpoint
};

}  // namespace

void multiscan_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int r0,
                    int r1, Image& out, Stats& stats) {
  const CameraFrame& cam = ps.camera;
  const int n = params.aa;
  Tracer tracer(ps, stats);
  SubLineBuilder builder(ps, tracer, stats, n, r0, r1 + 1);
  // Sub-scanline g lies at y = g / n: the same double in every band.
  auto line_at = [&](int g, SubLine& l) {
    const int row = std::min(g / n, cam.height - 1);
    builder.build(static_cast<double>(g) / n, row, l);
    stats.spans_total += l.spans;
    stats.spans_ray_traced += l.traced_spans;
  };
  std::vector<SubLine> lines(n + 1);
  std::vector<Figure> figs;
  for (int row = r0; row < r1; ++row) {
    // Sub-scanlines k = 0..n of this row; k = 0 is the previous row's k = n.
    if (row == r0) {
      line_at(row * n, lines[0]);
    } else {
      std::swap(lines.front(), lines.back());
    }
    for (int k = 1; k <= n; ++k) line_at(row * n + k, lines[k]);

    for (int i = 0; i < cam.width; ++i) {
      Color acc(0.0);
      bool traced = false;
      figs.clear();
      for (int k = 0; k <= n; ++k) {
        // Trapezoidal rule over the sub-scanlines.
        const double wk = (k == 0 || k == n) ? 0.5 / n : 1.0 / n;
        const SubLine& l = lines[k];
        for (int p = l.first[i]; p < l.first[i + 1]; ++p) {
          const Piece& pc = l.pieces[p];
          const double w = (pc.x1 - pc.x0) * wk;
          switch (pc.kind) {
            case Piece::kBackground:
              acc += w * ps.scene.background;
              break;
            case Piece::kTraced:
              acc += w * (k == n ? pc.colour_up : pc.colour);
              traced = true;
              break;
            case Piece::kFigure: {
              auto it = std::find_if(figs.begin(), figs.end(), [&](const Figure& f) {
                return f.face == pc.face && f.lights == pc.lights;
              });
              if (it == figs.end()) it = figs.insert(figs.end(), Figure{pc.face, pc.lights});
              const double xm = 0.5 * (pc.x0 + pc.x1);
              it->area += w;
              it->cx += w * xm;
              it->cy += w * l.y;
              if (w > it->rep_w) {
                it->rep_w = w;
                it->rep_x = xm;
                it->rep_y = l.y;
              }
              break;
            }
          }
        }
      }
      // Each figure shaded once, at the centroid of its area in the pixel
      // (its largest piece if the centroid falls off the face).
      for (const Figure& f : figs) {
        if (!(f.area > 0)) continue;
        const ScanFace& face = ps.scan->faces[f.face];
        FigureShadows known(f.lights);
        Ray ray{cam.from, cam.direction(f.cx / f.area, f.cy / f.area)};
        ++stats.tests_ray_object;
        auto hit = hit_on_face(ps, face, ray);
        if (!hit) {
          ray.dir = cam.direction(f.rep_x, f.rep_y);
          ++stats.tests_ray_object;
          hit = hit_on_face(ps, face, ray);
        }
        Color c;
        if (hit) {
          c = tracer.shade(ray, SurfaceHit{hit->t, face.prim, *hit}, 1, 1.0, nullptr, &known);
        } else {
          // A sliver grazing the face, or inside hither's sphere.
          ++stats.rays_eye;
          traced = true;
          c = tracer.trace(ray, cam.hither, 1, 1.0, nullptr);
        }
        acc += f.area * c;
      }
      if (traced) ++stats.pixels_ray_traced;
      store_pixel(out, band, i, row, acc);
    }
    stats.pixels_total += cam.width;
  }
}

}  // namespace locus
