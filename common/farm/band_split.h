// Cost-aware band splitting (issue #9 item 4): a cheap pre-pass predicts
// what each pixel row costs to render from the localization (which spans
// are ray traced, how many rays and shadow tests they need), and the rows
// are cut into bands of equal predicted cost instead of equal height.
// docs/farm.md "Cost-aware bands".
#pragma once

#include <vector>

#include "common/base/status.h"
#include "common/render.h"
#include "common/scene/scene.h"

namespace locus {

// The pre-pass renders at most this many rows (and proportionally fewer
// columns), point sampled.
inline constexpr int kPreviewRows = 64;

// Whether a frame cut into `bands` for a farm of `workers` gets the
// pre-pass at all. With many bands per worker the farm's leasing, a band
// at a time to whichever worker is free, balances equal heights about as
// well (the last band's tail is short), and the pre-pass, a preparation of
// the scene and a preview, only delays the first band: on 1 and 2 workers
// at 16 bands each, SPD gears and balls at 512x512 finished 0.2-0.4 s
// sooner with equal heights (docs/farm.md "Cost-aware bands").
inline constexpr int kCostSplitBandsPerWorker = 8;
bool cost_split_pays(int bands, int workers);

// Predicted relative cost of each of the scene's camera.height rows under
// `params` (the scene posed at the frame wanted). Deterministic: counts,
// not clocks; relative units (about one point-sampled diffuse pixel); the
// same for any `threads`, the threads of the pre-pass (its preparation and
// its rows; 0: one per core of the machine it runs on, whatever the job's
// --threads asks of its workers).
Result<std::vector<double>> predict_row_costs(const Scene& scene, const RenderParams& params,
                                              int threads = 0);

// Cuts rows [0, costs.size()) into `bands` bands of nearly equal total cost:
// edges[0] = 0 < edges[1] < ... < edges[bands] = costs.size(), so every band
// has at least one row. Requires 1 <= bands <= costs.size().
std::vector<int> split_rows_by_cost(const std::vector<double>& costs, int bands);

// An EXR job's band edges moved onto its frames' blocks of 16 rows
// (kExrZipBlockRows), so that each band's blocks are whole and compressed
// by the worker that rendered them (band_codec.h "exr+zip"): each inner
// edge of `edges` (empty: the equal split of band_rows) to the nearest
// multiple of 16 that leaves every band at least one block. Unchanged
// (`edges` as given) for more bands than the frame has blocks.
std::vector<int> align_band_edges(int height, int bands, const std::vector<int>& edges);

}  // namespace locus
