// Multi-scanning's sub-scanlines (paper §3.3, Figs. 4 and 5;
// docs/multiscan.md "What is computed"): the visible figures of one
// sub-scanline as pieces cut at pixel edges, built here (sub_line.cpp) and
// integrated into pixels by multiscan_rows (multiscan.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "common/base/cost.h"
#include "common/prepare/prepared.h"
#include "common/scan/eye_candidates.h"
#include "common/scan/pixel_samples.h"
#include "common/scan/scanline.h"
#include "common/scan/span_shadows.h"
#include "common/trace/raytrace.h"

namespace locus {

// A visible figure's piece of one sub-scanline, inside one pixel.
struct Piece {
  enum Kind : uint8_t { kBackground, kTraced, kFigure };
  double x0 = 0, x1 = 0;
  Kind kind = kBackground;
  int face = -1;  // kFigure: index into ScanScene::faces
  int hit = -1;   // kTraced: the first surface the sample met (-1: none)
  // A piece is traced or a figure, never both, so the two share their
  // storage: a piece is 80 bytes instead of 104 (a sub-scanline's pieces are
  // written once and read once per pixel row; on SPD tetra level 9, with
  // sub-pixel faces, they are about 400 KB a row).
  union {
    // kTraced: the piece's radiance for the pixel row below the
    // sub-scanline (or holding it), and on a row boundary also for the row
    // above (each row's pixels estimate it from their own samples;
    // PixelSamples).
    struct {
      Color colour, colour_up;
    } traced;
    LightStates lights{};  // kFigure: the state of the lights on the piece
  };
};
static_assert(sizeof(Piece) == 80);

// One sub-scanline: its pieces in x order, and pixel i's pieces
// [first[i], first[i + 1]).
struct SubLine {
  double y = 0;
  std::vector<Piece> pieces;
  std::vector<int> first;
  int spans = 0, traced_spans = 0;
};

// Builds the sub-scanlines of a chunk of pixel rows: the visible segments
// (visible_segments, paper §3.1), each cut into pieces by its kind: the
// background; diffuse faces' figures, cut where shadow intervals begin and
// end (§3.2 step 2); mirrors' and glass's samples; curved bodies' spans,
// whose true silhouettes are found by bisection (§3.3's convergence
// search) after a try at the body's outline (silhouette_guess).
class SubLineBuilder {
 public:
  // Lattice rows [j0, j1] (pixel corners y = j0..j1) may be used.
  // `meter` is charged with each piece's work as it is built (its pixel on
  // the meter's row), the line's and a span's set-up spread over their pixels.
  SubLineBuilder(const PreparedScene& ps, Tracer& tracer, Stats& stats, int aa, int j0, int j1,
                 CostMeter& meter);

  // Fills `line` (its allocations are reused) with sub-scanline y of `row`.
  void build(double y, int row, SubLine& line);

 private:
  // build()'s steps: the visible segments of the line and the queries set
  // to it; the pieces of each segment; pixel i's pieces.
  void start_line(double y, int row);
  void add_pieces(SubLine& line);
  void index_pixels(SubLine& line) const;

  // Calls fn(a, b) for the parts of [x0, x1) in each pixel, left to right.
  template <class Fn>
  void for_pixels(double x0, double x1, Fn&& fn);

  // Sampled with bisection: curved bodies' spans, and faces cut by hither.
  bool is_curved(const VisibleSegment& s) const {
    return s.face == -2 ||
           (s.face >= 0 && (scan_.faces[s.face].curved || scan_.faces[s.face].near_hither));
  }

  Ray eye_ray(double x) const { return Ray{cam_.from, cam_.direction(x, y_)}; }

  // The first surface along the eye ray at x, and its radiance.
  std::pair<int, Color> sample(double x);
  // The first surface along the eye ray at x (-1: none).
  int first_hit(double x);

  // Bisection (paper §3.3): where samples' keys differ, the x where they
  // change.
  template <class Key, class KeyAt, class Guess>
  void changes(double xl, Key kl, double xr, const Key& kr, KeyAt& key_at, Guess& guess,
               std::vector<std::pair<double, Key>>& out);
  template <class Key, class KeyAt, class Fill, class Guess>
  void refine(size_t begin, const std::vector<Key>& keys, KeyAt&& key_at, Fill&& fill,
              Guess&& guess, std::vector<std::pair<double, Key>>& found);
  // A curved body's outline where the first hit changes from kl to kr.
  bool silhouette_guess(double xl, int kl, double xr, int kr, double* x);

  // The pieces of each kind of span.
  void curved(double x0, double x1);
  void mirror(const VisibleSegment& s, SpanShadows* shadows);
  void figures(const VisibleSegment& s, SpanShadows& shadows);
  // Shadows by rays (ShadowPass): a diffuse face's span as figures, the
  // state of the lights from shadow rays at each pixel's piece, refined
  // where it changes; what states() gives at x on face f.
  void figures_by_rays(const VisibleSegment& s);
  // The point of face f that the eye ray `eye` meets.
  static Vec3 point_on(const ScanFace& f, const Ray& eye) {
    return face_point(f, eye.origin, eye.dir);
  }
  // The lights that cannot light any of face f (their bits), seen along
  // `eye` at its point p.
  uint64_t unlit_lights(const ScanFace& f, const Ray& eye, const Vec3& p) const;
  // The state of the lights at point p of face f.
  LightStates ray_states(const ScanFace& f, const Vec3& p, uint64_t unlit);
  // A traced piece's radiance (PixelSamples::colours).
  void traced_colours(Piece& p, FunctionRef<Color(double)> direct);

  const PreparedScene& ps_;
  const ScanScene& scan_;
  const CameraFrame& cam_;
  Tracer& tracer_;
  Stats& stats_;
  CostMeter& meter_;
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
  std::vector<Crossing> crossings_;  // ray_states'
  EyeCandidates eye_;
  PixelSamples samples_;  // traced pieces' radiance; uses eye_
  double sample_spacing_;  // pixels between sub-scanlines: 1 / --aa
};

}  // namespace locus
