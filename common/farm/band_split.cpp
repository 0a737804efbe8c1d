#include "common/farm/band_split.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/base/exr.h"
#include "common/base/parallel.h"
#include "common/farm/types.h"
#include "common/prepare/visibility.h"

namespace locus {

Result<std::vector<double>> predict_row_costs(const Scene& scene, const RenderParams& params,
                                              int threads) {
  const int w = scene.camera.width, h = scene.camera.height;
  if (w < 1 || h < 1) return InvalidArgument("predict_row_costs: empty image");
  // A preview of at most kPreviewRows rows with the same aspect: each of
  // its rows stands for `scale` rows of the frame.
  const int scale = std::max(1, (h + kPreviewRows - 1) / kPreviewRows);
  Scene preview = scene;
  preview.camera.width = std::max(1, w / scale);
  preview.camera.height = std::max(1, (h + scale - 1) / scale);
  // The frame's visible-surface and shadow passes, whatever the preview's
  // size and sampling would choose.
  RenderParams p = frame_passes(scene, params);
  p.threads = threads;
  p.aa = 0;   // the localization, point sampled
  p.spp = 1;
  // Before a job's first band, nothing else runs: the pre-pass is on every
  // core (gears at 512x512: 0.59 s on one, 0.31 s on two).
  const int preview_rows = preview.camera.height;
  auto prepared = prepare_scene(std::move(preview), p);
  if (!prepared.ok()) return prepared.status();
  const int row_threads = render_threads(p);
  p.threads = 1;  // a row each
  // Weights of the counters in units of one point-sampled diffuse pixel.
  // Chosen on scene (d) at 512x512, --aa 4, 8 bands (bench/farm
  // locus-band-balance; kSpan 2 and kRay 4 gave an imbalance of 1.36, these
  // 1.21-1.23): with multi-scanning a span's work (visible intervals and
  // shadow intervals on every sub-scanline) weighs more than its pixels,
  // and a ray with its shading about as much as 8 diffuse pixels.
  constexpr double kPixel = 1.0, kSpan = 10.0, kRay = 8.0, kShadowRay = 1.0, kVolumeTest = 0.05,
                   kObjectTest = 0.1;
  std::vector<double> costs(h, 1.0);
  // Rows side by side, each writing only its own frame rows.
  parallel_for(preview_rows, row_threads, [&](int r) {
    const BandResult band = render_band(**prepared, Band{r, r + 1}, p);
    const Stats& s = band.stats;
    const double c = kPixel * static_cast<double>(s.pixels_total) +
                     kSpan * static_cast<double>(s.spans_total) +
                     kRay * static_cast<double>(s.rays_eye + s.rays_reflected + s.rays_refracted) +
                     kShadowRay * static_cast<double>(s.rays_shadow) +
                     kVolumeTest * static_cast<double>(s.tests_shadow_volume) +
                     kObjectTest * static_cast<double>(s.tests_ray_object);
    // Each of the preview row's `scale` frame rows gets an equal share
    // (only ratios matter).
    const double per_row = c / scale;
    for (int y = r * scale; y < std::min(h, (r + 1) * scale); ++y) costs[y] = per_row;
  });
  return costs;
}

bool cost_split_pays(int bands, int workers) {
  return bands > 1 && bands < kCostSplitBandsPerWorker * std::max(workers, 1);
}

std::vector<int> split_rows_by_cost(const std::vector<double>& costs, int bands) {
  const int h = static_cast<int>(costs.size());
  bands = std::clamp(bands, 1, std::max(1, h));
  std::vector<double> prefix(h + 1, 0.0);
  for (int y = 0; y < h; ++y) prefix[y + 1] = prefix[y] + std::max(0.0, costs[y]);
  std::vector<int> edges(bands + 1, 0);
  edges[bands] = h;
  for (int b = 1; b < bands; ++b) {
    // The first row edge at or past b/bands of the total cost, kept inside
    // [previous edge + 1, h - (bands - b)] so that every band has a row.
    const double target = prefix[h] * b / bands;
    int y = static_cast<int>(std::lower_bound(prefix.begin(), prefix.end(), target) - prefix.begin());
    // Of the two rows around the target, the nearer.
    if (y > 0 && target - prefix[y - 1] < prefix[y] - target) --y;
    edges[b] = std::clamp(y, edges[b - 1] + 1, h - (bands - b));
  }
  return edges;
}

std::vector<int> align_band_edges(int height, int bands, const std::vector<int>& edges) {
  const int blocks = (height + kExrZipBlockRows - 1) / kExrZipBlockRows;
  if (bands < 1 || bands > blocks) return edges;
  std::vector<int> aligned{0};
  for (int i = 1; i < bands; ++i) {
    const int edge = farm::band_rows(height, bands, edges, i).y0;
    const int nearest = (edge + kExrZipBlockRows / 2) / kExrZipBlockRows;
    // At least a block after the previous edge, and a block for each band
    // still to come.
    const int block =
        std::clamp(nearest, aligned.back() / kExrZipBlockRows + 1, blocks - (bands - i));
    aligned.push_back(block * kExrZipBlockRows);
  }
  aligned.push_back(height);
  return aligned;
}

}  // namespace locus
