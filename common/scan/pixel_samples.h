// Multi-scanning's radiance of ray-traced pieces (paper §3.3; issue #6 item 3;
// docs/multiscan.md "Inside mirrors and glass"). The paper samples every
// piece of a ray-traced span: one ray per pixel per sub-scanline. Here the
// pieces share samples at the pixels' corners and on stratified grids
// inside the pixels, each traced once on first use, and a piece samples
// itself only where none of its pixel's samples sees its material.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include "common/base/function_ref.h"
#include "common/prepare/prepared.h"
#include "common/scan/eye_candidates.h"
#include "common/trace/raytrace.h"

namespace locus {

// A traced piece's radiance for the pixel row below its sub-scanline (or
// holding it), and on a row boundary also for the row above; zero for a row
// outside the samples' rows.
struct PieceColours {
  Color colour{0.0}, colour_up{0.0};
};

class PixelSamples {
 public:
  // For multi-scanning with N = aa sub-scanlines per pixel row. Lattice rows
  // [j0, j1] (pixel corners y = j0..j1) may be used; the pieces' radiance is
  // estimated for pixel rows [j0, j1 - 1). `eye` gives the candidates of the
  // samples' eye rays.
  PixelSamples(const PreparedScene& ps, Tracer& tracer, EyeCandidates& eye, Stats& stats, int aa,
               int j0, int j1);

  // A new sub-scanline at y: the pixel rows whose pixels its traced pieces
  // are estimated for are the row that holds it, and on a row boundary the
  // row above, which it closes.
  void set_line(double y);

  // The radiance of the traced piece [x0, x1) of the current sub-scanline,
  // whose sample at its middle first met primitive `hit` (>= 0), for each
  // of the rows set_line chose. `direct(x)` samples the piece itself at x
  // (traced at most once, for both rows).
  PieceColours colours(double x0, double x1, int hit, FunctionRef<Color(double)> direct);

 private:
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

  // The piece's radiance for the pixels of row j (y_ in [j, j + 1]).
  template <class Direct>
  Color traced_colour(double x0, double x1, int hit, int j, Direct&& direct);

  // Pixel (i, j)'s interior samples, a grid_ x grid_ grid, and the grid
  // twice as fine, each traced on first use.
  const Corner* interior(int i, int j) { return grid_samples(i, j, grid_, interior_); }
  const Corner* fine(int i, int j) { return grid_samples(i, j, 2 * grid_, fine_); }
  const Corner* grid_samples(int i, int j, int g, RowRing& store);
  // Point q of the fine grid alone (silhouettes).
  const Corner& fine_point(int i, int j, int q);
  // Traces point q of pixel (i, j)'s g x g grid into k, once.
  void grid_point(Corner& k, int i, int j, int g, int q);
  const Corner& corner(int i, int j);

  int material_of(int prim) const { return ps_.object_material[ps_.prims.prims[prim].object]; }

  const PreparedScene& ps_;
  const CameraFrame& cam_;
  Tracer& tracer_;
  EyeCandidates& eye_;
  Stats& stats_;
  int j0_, j1_;
  double y_ = 0;
  int row_down_ = -1, row_up_ = -1;  // set_line's rows (-1: none)
  int grid_;                         // max(1, aa / 4)
  bool centre_only_;                 // N = 1: a pixel's interior is its centre (pixel_samples.cpp)
  RowRing lattice_;                  // pixel corners, a row of them per lattice row
  RowRing interior_, fine_;          // per pixel row
};

}  // namespace locus
