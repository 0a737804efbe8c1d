// Multi-scanning's pixel integration (paper §3.3; docs/multiscan.md "What is
// computed"): the pieces of a pixel row's sub-scanlines (built by
// SubLineBuilder, sub_line.h) give, by the trapezoidal rule, the area each
// figure covers in each pixel; each figure is shaded once per pixel, and the
// pixel is the area-weighted sum.
#include "common/scan/multiscan.h"

#include <algorithm>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "common/base/prefetch.h"
#include "common/scan/sub_line.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace {

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

// One figure's share of a pixel, summed over the sub-scanlines.
struct Figure {
  int face;
  LightStates lights;
  double area = 0, cx = 0, cy = 0;
  double rep_w = -1, rep_x = 0, rep_y = 0;  // its largest piece's midpoint
};

// The pixels of one row from its sub-scanlines k = 0..n.
class PixelIntegrator {
 public:
  PixelIntegrator(const PreparedScene& ps, Tracer& tracer, Stats& stats, CostMeter& meter)
      : ps_(ps), cam_(ps.camera), tracer_(tracer), stats_(stats), meter_(meter) {}

  // Pixel i of the row whose sub-scanlines are `lines`.
  Color pixel(const std::vector<SubLine>& lines, int i) {
    Color acc(0.0);
    const bool traced_piece = integrate_pieces(lines, i, acc);
    const bool traced_figure = shade_figures(acc);
    meter_.charge(i);
    if (traced_piece || traced_figure) {
      ++stats_.pixels_ray_traced;
      meter_.mark_traced(i, traced_piece);
    }
    return acc;
  }

 private:
  // Trapezoidal rule over the sub-scanlines (weights 1/(2n) for k = 0 and
  // n, 1/n between): the background's and traced pieces' radiance times
  // their area is added to `acc`, the figures' areas and centroids are
  // summed into figs_. Returns whether a traced piece lies in the pixel.
  bool integrate_pieces(const std::vector<SubLine>& lines, int i, Color& acc) {
    const int n = static_cast<int>(lines.size()) - 1;
    bool traced = false;
    figs_.clear();
    for (int k = 0; k <= n; ++k) {
      const double wk = (k == 0 || k == n) ? 0.5 / n : 1.0 / n;
      const SubLine& l = lines[k];
      for (int p = l.first[i]; p < l.first[i + 1]; ++p) {
        const Piece& pc = l.pieces[p];
        const double w = (pc.x1 - pc.x0) * wk;
        switch (pc.kind) {
          case Piece::kBackground:
            acc += w * ps_.scene.background;
            break;
          case Piece::kTraced:
            acc += w * (k == n ? pc.traced.colour_up : pc.traced.colour);
            traced = true;
            break;
          case Piece::kFigure:
            add_to_figure(pc, w, l.y);
            break;
        }
      }
    }
    return traced;
  }

  // Piece `pc` of sub-scanline y, of weighted length w, into its figure
  // (its face under its state of the lights).
  void add_to_figure(const Piece& pc, double w, double y) {
    auto it = std::find_if(figs_.begin(), figs_.end(), [&](const Figure& f) {
      return f.face == pc.face && f.lights == pc.lights;
    });
    if (it == figs_.end()) {
      it = figs_.insert(figs_.end(), Figure{pc.face, pc.lights});
      fetch_early(ps_.scan->faces[pc.face].prim);
    }
    const double xm = 0.5 * (pc.x0 + pc.x1);
    it->area += w;
    it->cx += w * xm;
    it->cy += w * y;
    if (w > it->rep_w) {
      it->rep_w = w;
      it->rep_x = xm;
      it->rep_y = y;
    }
  }

  // Each figure shaded once, at the centroid of its area in the pixel (its
  // largest piece if the centroid falls off the face), with the state of
  // the lights known; its radiance times its area is added to `acc`.
  // Returns whether a ray was traced (a figure missed its face).
  bool shade_figures(Color& acc) {
    bool traced = false;
    for (const Figure& f : figs_) fetch_before_shading(ps_.scan->faces[f.face].prim);
    for (const Figure& f : figs_) {
      if (!(f.area > 0)) continue;
      const ScanFace& face = ps_.scan->faces[f.face];
      FigureShadows known(f.lights);
      Ray ray{cam_.from, cam_.direction(f.cx / f.area, f.cy / f.area)};
      ++stats_.tests_ray_object;
      auto hit = hit_on_face(ps_, face, ray);
      if (!hit) {
        ray.dir = cam_.direction(f.rep_x, f.rep_y);
        ++stats_.tests_ray_object;
        hit = hit_on_face(ps_, face, ray);
      }
      Color c;
      if (hit) {
        c = tracer_.shade(ray, SurfaceHit{hit->t, face.prim, *hit}, 1, 1.0, nullptr, &known);
      } else {
        // A sliver grazing the face, or inside hither's sphere.
        ++stats_.rays_eye;
        traced = true;
        c = tracer_.trace(ray, cam_.hither, 1, 1.0, nullptr);
      }
      acc += f.area * c;
    }
    return traced;
  }

  // What shading a figure of primitive `prim` reads, asked of the memory
  // ahead of time: where faces are many (SPD tetra level 9: 262,144, each
  // a figure of its own in a pixel or two) each is a cache miss, and a
  // pixel's figures are independent of each other. When a figure is first
  // met, the primitive's slot and its PrimRef (fetch_early); when the
  // pixel's figures are shaded, those two loaded by then, its leaf copy
  // (hit_on_face) and its object's material (Tracer::shade). Render CPU at
  // 512², --aa 4, without them: level 9 1.027x, level 7 0.99x
  // (docs/renderer.md, "Session 42").
  void fetch_early(int prim) const {
    if (!ps_.leaf_slot.empty()) prefetch(&ps_.leaf_slot[prim]);
    prefetch(&ps_.prims.prims[prim]);
  }
  void fetch_before_shading(int prim) const {
    if (const int slot = ps_.leaf_slot_of(prim); slot >= 0) {
      const char* lp = reinterpret_cast<const char*>(&ps_.leaf_prims[slot]);
      prefetch(lp);
      prefetch(lp + 64);
      prefetch(lp + sizeof(LeafPrim) - 1);
    }
    prefetch(&ps_.object_material[ps_.prims.prims[prim].object]);
  }

  const PreparedScene& ps_;
  const CameraFrame& cam_;
  Tracer& tracer_;
  Stats& stats_;
  CostMeter& meter_;
  std::vector<Figure> figs_;
};

}  // namespace

void multiscan_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int r0,
                    int r1, Image& out, Stats& stats, FunctionRef<bool(int)> row_may_start,
                    CostBuffer* cost) {
  const CameraFrame& cam = ps.camera;
  const int n = params.aa;
  CostMeter meter(cost, stats);
  Tracer tracer(ps, stats);
  SubLineBuilder builder(ps, tracer, stats, n, r0, r1 + 1, meter);
  PixelIntegrator integrator(ps, tracer, stats, meter);
  // Sub-scanline g lies at y = g / n: the same double in every band.
  auto line_at = [&](int g, SubLine& l) {
    const int row = std::min(g / n, cam.height - 1);
    builder.build(static_cast<double>(g) / n, row, l);
    stats.spans_total += l.spans;
    stats.spans_ray_traced += l.traced_spans;
  };
  std::vector<SubLine> lines(n + 1);
  for (int row = r0; row < r1; ++row) {
    if (!row_may_start(row)) return;
    meter.set_row(row);
    // Sub-scanlines k = 0..n of this row; k = 0 is the previous row's k = n.
    if (row == r0) {
      line_at(row * n, lines[0]);
    } else {
      std::swap(lines.front(), lines.back());
    }
    for (int k = 1; k <= n; ++k) line_at(row * n + k, lines[k]);
    for (int i = 0; i < cam.width; ++i) store_pixel(out, band, i, row, integrator.pixel(lines, i));
    stats.pixels_total += cam.width;
    meter.charge_run(0, cam.width);  // what no pixel took (nothing, as written)
  }
}

}  // namespace locus
