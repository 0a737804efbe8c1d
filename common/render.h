// The renderer's entry points, above every stage: a worker prepares a frame
// once (prepare_scene, common/prepare/prepared.h) and renders bands of it
// (render_band); a whole image is one band (render_image).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "common/base/cost.h"
#include "common/base/image.h"
#include "common/base/params.h"
#include "common/base/status.h"
#include "common/prepare/prepared.h"
#include "common/scene/scene.h"

namespace locus {

struct BandResult {
  Image pixels;  // width x (y1 - y0)
  Stats stats;
  // The band was cancelled before every row was rendered: its pixels are
  // incomplete and must not be used.
  bool cancelled = false;
};

// Renders rows [band.y0, band.y1). Every pixel depends only on the scene,
// the parameters and its own coordinates, so a band stitched into a frame is
// bit-identical to the same rows of an unbanded render.
// `cancel`, if given, is checked before every row: once it is set, the band
// stops within one row per thread and comes back `cancelled` (a band whose
// lease was taken back frees its worker; issue #23 item 5).
// `cost`, if given, is reset to the band's rows and gets each pixel's share
// of the band's Stats (common/base/cost.h; docs/cost-map.md); the pixels are
// the same with or without it.
BandResult render_band(const PreparedScene& prepared, const Band& band, const RenderParams& params,
                       const std::atomic<bool>* cancel = nullptr, CostBuffer* cost = nullptr);

// Tests only: `hook(row)` runs before each row of every render_band, on the
// rendering thread (a hang placed inside the renderer, to test what the
// farm does with a band that never returns). Empty: none. Set it only while
// nothing renders.
void set_row_hook_for_test(std::function<void(int row)> hook);

// prepare_scene + render_band over the whole image; stats include prepare time.
// `cost`, if given, as render_band's.
Result<BandResult> render_image(Scene scene, const RenderParams& params,
                                CostBuffer* cost = nullptr);

// render_image for one frame of an animation, prepared by `geometry`
// (AnimationGeometry::prepare: `view` the frame's camera, `frame` its whole
// scene where it is prepared afresh).
Result<BandResult> render_frame(AnimationGeometry& geometry, const Camera& view,
                                FunctionRef<Scene()> frame, const RenderParams& params,
                                CostBuffer* cost = nullptr);

}  // namespace locus
