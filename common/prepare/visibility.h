// The local method's choice of visible-surface pass, per frame (issue #27;
// docs/renderer.md "Visibility by rays"). The scanline pass (paper §3.2)
// gains from image coherence: a face spans many pixels of a row and many
// rows. Point sampled (--aa 0) it computes the very samples an eye ray per
// pixel would, and where many faces cross each row (SPD tetra at level 8-9,
// balls at level 5: faces finer than the pixels) it pays per face and per
// row, builds and tests shadow volumes of sub-pixel occluders for every
// light, and an eye ray per sample through the boxes is far cheaper. The
// choice is made before anything per face is built, from the primitives'
// boxes alone, so a frame that casts rays never pays for the scan scene or
// the volumes. Multi-scanned frames always scan: their exact coverage is the
// method's point (paper §3.3).
//
// A scanned frame of configuration IV then finds the shadows of its spans by
// shadow volumes (paper §3.2 step 2) or, where the occluders outnumber what
// the image can resolve, by shadow rays through the boxes (ShadowPass;
// docs/renderer.md "Shadows by rays"), from the same measure.
#pragma once

#include "common/base/params.h"
#include "common/geometry/geometry.h"

namespace locus {

struct CameraFrame;  // common/prepare/prepared.h

// What the choice was made from: the primitives' boxes projected on the
// image (clipped to it; a box reaching behind the eye counts as the whole
// image).
struct VisibilityMeasure {
  // The rows crossed by the projected boxes of the primitives in view,
  // summed.
  double face_rows = 0;
  // face_rows of what the scanline pass would ray trace in any case: curved
  // bodies and CSG (their true surface), mirrors and glass (paper §3.2).
  double traced_rows = 0;
  // The primitives in view (their boxes meet the image): the occluders whose
  // volumes the scanline pass would build and test.
  double in_view = 0;
  // The scene's lights: each occluder has a volume per light.
  int lights = 0;
};

VisibilityMeasure measure_visibility(const Scene& scene, const PrimitiveSet& prims,
                                     const CameraFrame& cam);

// True: find visible surfaces by eye rays (Visibility::kRays). `params`'
// visibility decides unless it is kAuto; configurations II and III always
// scan (their boxes are the paper's experiment, METHOD.md §8).
bool visibility_by_rays(const VisibilityMeasure& m, const CameraFrame& cam,
                        const RenderParams& params);

// True: a scanned frame finds its spans' shadows by rays, no volumes built
// (ShadowPass::kRays). `params`' shadows decide unless kAuto; II and III
// always build volumes.
bool shadows_by_rays(const VisibilityMeasure& m, const CameraFrame& cam,
                     const RenderParams& params);

// `params` with kAuto visibility and shadows resolved for `scene` as
// prepare_scene() would resolve them (kAuto is kept where a choice does not
// apply): for a preview at another size or sampling (farm/band_split.h) that
// must pass the way its frame will.
RenderParams frame_passes(const Scene& scene, const RenderParams& params);

}  // namespace locus
