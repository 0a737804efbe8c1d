// Which primitives an eye ray can meet, from the scanline pass's outlines
// (paper §3.2: the scanline pass localizes the search; docs/multiscan.md).
// A ray that meets a primitive passes inside the outline of one of the
// primitive's faces (of its bounding polyhedron, for a curved body), so the
// primitives of the faces whose outlines hold the ray's image point are the
// only ones it can meet. Where a face reaches into hither's sphere or a
// bounding polyhedron holds the eye the outlines do not tell (`active()`
// is false), and the caller searches everything.
#pragma once

#include <optional>
#include <vector>

#include "common/scan/pixel_buckets.h"
#include "common/scan/scanline.h"
#include "common/trace/raytrace.h"

namespace locus {

class EyeCandidates {
 public:
  // For image points of pixel rows [j0, j1) (a point on row j1's top edge
  // belongs to row j1 - 1).
  EyeCandidates(const ScanScene& scan, int width, int j0, int j1);

  bool active() const { return active_; }

  // A new sub-scanline: `ivs` are the intervals of the faces crossing it
  // (VisibleScratch::ivs), valid until the next call.
  void set_line(const std::vector<DepthInterval>& ivs);
  // The primitives whose faces' intervals on the current sub-scanline hold
  // x.
  const std::vector<int>& on_line(double x);
  // The primitives whose faces' outlines meet the closed pixel square that
  // holds image point (x, y).
  const std::vector<int>& in_square(double x, double y);

  // The nearest surface beyond `hither` along `ray`, the eye ray through
  // image point (x, y), searched among the primitives whose outlines hold
  // the point: on the current sub-scanline (y is that line), those of its
  // intervals (on_line); elsewhere those meeting its pixel square
  // (in_square). Where the outlines do not tell (!active()), among all.
  std::optional<SurfaceHit> nearest_on_line(Tracer& tracer, const Ray& ray, double hither,
                                            double x) {
    if (!active_) return tracer.nearest(ray, hither, kInf);
    return tracer.nearest_among(ray, hither, kInf, on_line(x));
  }
  std::optional<SurfaceHit> nearest_in_square(Tracer& tracer, const Ray& ray, double hither,
                                              double x, double y) {
    if (!active_) return tracer.nearest(ray, hither, kInf);
    return tracer.nearest_among(ray, hither, kInf, in_square(x, y));
  }

 private:
  const ScanScene& scan_;
  int width_, j0_, j1_;
  bool active_;
  const std::vector<DepthInterval>* ivs_ = nullptr;
  bool line_built_ = false;
  PixelBuckets line_;  // the current line's intervals, per pixel
  // Per row from j0: the faces meeting each pixel square (`row_faces_[r][k]`
  // is item k of `rows_[r]`), built on first use.
  std::vector<PixelBuckets> rows_;
  std::vector<std::vector<int>> row_faces_;
  std::vector<int> prims_;
};

}  // namespace locus
