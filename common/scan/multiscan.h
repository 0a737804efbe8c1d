// Multi-scanning anti-aliasing of the local method (paper §3.3, Figs. 4
// and 5; METHOD.md §6; docs/multiscan.md).
//
// Each pixel row j is cut by sub-scanlines at y = j + k/N, k = 0..N (N =
// RenderParams::aa). On each sub-scanline the visible figures are exact
// x-intervals: faces resolved by depth (split where the depth order
// changes), cut where shadow intervals begin and end. Their lengths inside
// each pixel, integrated over the sub-scanlines by the trapezoidal rule, are
// the areas the figures cover; the pixel is the area-weighted sum of the
// figures' intensities. A figure (a face under one state of the lights) is
// shaded once per pixel, at the centroid of its area there.
//
// Ray-traced spans (mirrors, glass, curved bodies' bounding polyhedra) take
// one sample per pixel per sub-scanline, interpolated from shared pixel-
// corner samples where those agree, and N/2 samples where the reflected or
// refracted image has an edge (docs/multiscan.md). Inside a bounding polyhedron, where
// the first surface hit changes between neighbouring samples, bisection
// finds the true silhouette to kBisectTolerance (a sphere's or cone's
// outline is tried first, and then found exactly); so does it where the
// shadow of a curved or transparent occluder begins, unless that shadow's
// interval is exact (an opaque sphere or cone between face and light).
//
// In three parts: SubLineBuilder (sub_line.h) builds each sub-scanline's
// pieces, PixelSamples (pixel_samples.h) gives traced pieces their radiance,
// and multiscan_rows (multiscan.cpp) integrates the pieces into pixels.
#pragma once

#include "common/base/cost.h"
#include "common/base/function_ref.h"
#include "common/base/image.h"
#include "common/base/params.h"
#include "common/prepare/prepared.h"

namespace locus {

// Silhouettes and curved shadow edges are located to this many pixels.
inline constexpr double kBisectTolerance = 1.0 / 64;

// Renders pixel rows [r0, r1) of the band into `out` (row - band.y0). A
// sub-scanline is a function of its y alone, so any split into bands or
// chunks gives the same pixels; inside [r0, r1) the boundary sub-scanline of
// two rows is computed once. `row_may_start(row)` is asked before each row;
// false stops there (a band no longer wanted, render_band). `cost`, if
// given, gets the rows' share of `stats` per pixel (cost.h): a sub-scanline's
// work goes to the pixel row that computes it (docs/cost-map.md).
void multiscan_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int r0,
                    int r1, Image& out, Stats& stats, FunctionRef<bool(int)> row_may_start,
                    CostBuffer* cost = nullptr);

}  // namespace locus
