// Where a render's work went, per pixel (issue #27 item 5; docs/cost-map.md):
// the rays by kind and the shadow-volume tests (paper §4.1) charged to the
// pixels they were spent on, and whether the pixel was ray traced (the spans
// the local method ray traces, paper §3.2). Stats counts the same things for
// a whole band; a cost buffer splits those totals over its pixels, so that
// its counts sum to them. The picture made of it is cost_map.h's.
#pragma once

#include <cstdint>
#include <vector>

#include "common/base/params.h"

namespace locus {

// One pixel's share of a band's Stats.
struct PixelCost {
  uint32_t rays_eye = 0;
  uint32_t rays_reflected = 0;
  uint32_t rays_refracted = 0;
  uint32_t rays_shadow = 0;
  uint32_t tests_shadow_volume = 0;
  // An eye, reflected or refracted ray was cast for the pixel: it is counted
  // in Stats::pixels_ray_traced.
  bool traced = false;
  // The pixel lies in a span the local method ray traces (paper §3.2;
  // METHOD.md §4): a mirror's or glass's, or a curved body's bounding
  // polyhedron's (or, seldom, a face cut by hither's sphere). The other
  // traced pixels are those where the scanline's face was missed by the
  // pixel's sample (an edge grazed) and an eye ray decided.
  bool traced_span = false;

  uint64_t rays() const {
    return uint64_t{rays_eye} + rays_reflected + rays_refracted + rays_shadow;
  }
  // The cost map's measure: every ray and every shadow-volume test counts 1.
  uint64_t work() const { return rays() + tests_shadow_volume; }
};

// The pixels of rows [y0, y1) of a frame, row-major.
struct CostBuffer {
  int width = 0;
  int y0 = 0;
  int y1 = 0;
  std::vector<PixelCost> pixels;

  // Zeroed, for rows [y0, y1) of a frame `width` pixels wide.
  void reset(int width, int y0, int y1);
  int height() const { return y1 - y0; }
  // Frame pixel (x, y).
  PixelCost& at(int x, int y) { return pixels[static_cast<size_t>(y - y0) * width + x]; }
  const PixelCost& at(int x, int y) const {
    return pixels[static_cast<size_t>(y - y0) * width + x];
  }
  // The counts summed over the buffer, as a Stats (the other fields zero),
  // and the number of traced pixels in pixels_ray_traced.
  Stats totals() const;
};

// Charges a thread's Stats to the pixels of a cost buffer as a row loop goes
// along: each charge gives the pixel (or run of pixels) the counts added to
// `stats` since the previous charge, the work done for it. A row loop makes
// one when it starts (nothing uncharged lies before it) and charges the whole
// row last (work of the row as a whole), so that every count lands on some
// pixel. With no buffer every call is a test of one pointer: rendering
// without a cost map does no more.
class CostMeter {
 public:
  CostMeter(CostBuffer* buffer, const Stats& stats) : buf_(buffer), stats_(stats) {
    if (buf_) last_ = Counts::of(stats_);
  }

  // The frame row that later charges go to.
  void set_row(int y) { row_ = y; }
  // The counts since the last charge to the pixel of the row holding image
  // x coordinate x (pixel floor(x)).
  void charge(double x) {
    if (buf_) charge_run_(x, x);
  }
  // ... spread evenly over the pixels of the row that [x0, x1] touches
  // (floor(x0) to ceil(x1), clamped to the image; at least one): work done
  // for a whole span.
  void charge_run(double x0, double x1) {
    if (buf_) charge_run_(x0, x1);
  }
  // Pixel x of the row was ray traced; `span`: in a ray-traced span.
  void mark_traced(int x, bool span) {
    if (buf_) {
      PixelCost& p = buf_->at(x, row_);
      p.traced = true;
      p.traced_span = span;
    }
  }

 private:
  // The counters of Stats that a PixelCost splits.
  struct Counts {
    uint64_t n[5] = {};
    static Counts of(const Stats& s) {
      return {
          {s.rays_eye, s.rays_reflected, s.rays_refracted, s.rays_shadow, s.tests_shadow_volume}};
    }
  };
  void charge_run_(double x0, double x1);

  CostBuffer* buf_;
  const Stats& stats_;
  Counts last_;
  int row_ = 0;
};

}  // namespace locus
