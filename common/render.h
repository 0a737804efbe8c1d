// The renderer's entry points, above every stage: a worker prepares a frame
// once (prepare_scene, common/prepare/prepared.h) and renders bands of it
// (render_band); a whole image is one band (render_image).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "common/base/image.h"
#include "common/base/params.h"
#include "common/base/status.h"
#include "common/prepare/prepared.h"
#include "common/scene/scene.h"

namespace locus {

struct BandResult {
  Image pixels;  // width x (y1 - y0)
  Stats stats;
};

// Renders rows [band.y0, band.y1). Every pixel depends only on the scene,
// the parameters and its own coordinates, so a band stitched into a frame is
// bit-identical to the same rows of an unbanded render.
BandResult render_band(const PreparedScene& prepared, const Band& band, const RenderParams& params);

// prepare_scene + render_band over the whole image; stats include prepare time.
Result<BandResult> render_image(const Scene& scene, const RenderParams& params);

}  // namespace locus
