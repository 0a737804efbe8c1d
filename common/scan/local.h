// The local method (paper §3.2; METHOD.md §4): visibility from the scanline
// pass, ray tracing only where it is needed.
#pragma once

#include "common/base/image.h"
#include "common/base/params.h"
#include "common/prepare/prepared.h"

namespace locus {

// Renders row `row` of the band into `out` (row - band.y0).
void local_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int row,
                Image& out, Stats& stats);

}  // namespace locus
