// The local method (paper §3.2; METHOD.md §4): visibility from the scanline
// pass, ray tracing only where it is needed.
#pragma once

#include "common/base/cost.h"
#include "common/base/image.h"
#include "common/base/params.h"
#include "common/prepare/prepared.h"

namespace locus {

// Renders row `row` of the band into `out` (row - band.y0). `cost`, if
// given, gets the row's share of `stats` per pixel (cost.h).
void local_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int row,
                Image& out, Stats& stats, CostBuffer* cost = nullptr);

}  // namespace locus
