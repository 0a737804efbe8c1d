#include "common/prepare/visibility.h"

#include <algorithm>
#include <cmath>

#include "common/prepare/prepared.h"
#include "common/prepare/tessellate.h"

namespace locus {

VisibilityMeasure measure_visibility(const Scene& scene, const PrimitiveSet& prims,
                                     const CameraFrame& cam) {
  VisibilityMeasure m;
  const double w = cam.width, h = cam.height;
  for (size_t i = 0; i < prims.bounds.size(); ++i) {
    const Aabb& b = prims.bounds[i];
    if (b.empty()) continue;
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    bool behind = false;
    for (int c = 0; c < 8 && !behind; ++c) {
      const Vec3 p{c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z};
      if (glm::dot(p - cam.from, cam.w) <= 0.0) {
        behind = true;
        break;
      }
      const Vec2 q = cam.project(p);
      x0 = std::min(x0, q.x);
      x1 = std::max(x1, q.x);
      y0 = std::min(y0, q.y);
      y1 = std::max(y1, q.y);
    }
    if (behind) {
      x0 = y0 = 0.0;
      x1 = w;
      y1 = h;
    }
    x0 = std::max(x0, 0.0);
    y0 = std::max(y0, 0.0);
    x1 = std::min(x1, w);
    y1 = std::min(y1, h);
    if (x0 > x1 || y0 > y1) continue;
    // A box thinner than a pixel still costs the scanline a row.
    const double rows = std::max(y1 - y0, 1.0);
    m.face_rows += rows;
    m.in_view += 1;
    const PrimRef& ref = prims.prims[i];
    const Material& mat = scene.materials[scene.objects[ref.object].material];
    const bool curved =
        ref.kind == PrimKind::kSphere || ref.kind == PrimKind::kCone || ref.kind == PrimKind::kCsg;
    if (curved || mat.ks > 0 || mat.t > 0) m.traced_rows += rows;
  }
  return m;
}

namespace {
// Point sampled, the scanline pass computes the samples an eye ray per
// pixel would. Measured side by side on 26 scenes at 512x512 (docs/
// renderer.md "Visibility by rays", the table there), it is faster on
// scenes of a few large faces (the paper's (a)-(d), jacks: at most 7 boxes
// per row), and rays are faster from 28 per row up where most of the rows'
// boxes are traced in any case (balls level 3, tree); where they are
// diffuse faces, the scanline stays faster up to 34 per row (tetra levels 3
// and 4, by 3x), ties at 69-71 (tetra level 5, teapot) and loses from 138
// (tetra level 6; sombrero at 43 loses by 1.3x, the one miss).
constexpr double kRaysPerRow = 16;
constexpr double kRaysPerRowDiffuse = 64;
}  // namespace

bool visibility_by_rays(const VisibilityMeasure& m, const CameraFrame& cam,
                        const RenderParams& params) {
  if (!configuration_iv(params)) return false;
  if (params.visibility != Visibility::kAuto) return params.visibility == Visibility::kRays;
  // Multi-scanned, the scanline pass gives every figure's exact coverage of
  // its pixels (paper §3.3), which sampling by rays does not match: on tree
  // and tetra level 8 rays at --aa 8 left twice the scanline's error
  // (docs/renderer.md). So it scans, whatever it costs.
  if (params.aa > 0) return false;
  // Primitives' boxes crossed by the average row: what the scanline pass
  // pays per row, with a box thinner than a row counted as one.
  const double per_row = m.face_rows / std::max(1, cam.height);
  const double traced_share = m.face_rows > 0 ? m.traced_rows / m.face_rows : 0.0;
  return per_row >= kRaysPerRow && (traced_share >= 0.5 || per_row >= kRaysPerRowDiffuse);
}

namespace {
// Shadow volumes pay per occluder: each is built for every light and tested
// wherever it covers a span, exactly (paper §3.2 step 2). Rays pay per
// sample. Measured side by side at --aa 4 and 8 (docs/renderer.md "Shadows
// by rays", the tables there): on the SPD big levels (balls 5, tetra 8 and
// 9: 128 to 512 primitives in view per image row at 512x512) rays win by
// 2.6-4.3x at equal error or better on the speed/accuracy curve, with a
// third of the memory; at 256x256, where balls, gears, rings, tree and
// mount have 29 to 36 per row, rays are 1.7-3.7x faster for 2-48% more
// error at the same --aa, and better on the curve (each one's --aa 8 by
// rays costs about what --aa 4 by volumes does, with less error). At
// 512x512 the same scenes (9 to 18 per row) are faster by rays too, with
// up to 41% more error (gears), and below that (the paper's scenes, tetra
// level 6 at 8 per row, sombrero) the volumes are faster. So rays where
// an average row meets 24 occluders or more.
constexpr double kShadowRaysPerRow = 24;
}  // namespace

bool shadows_by_rays(const VisibilityMeasure& m, const CameraFrame& cam,
                     const RenderParams& params) {
  if (!configuration_iv(params)) return false;
  if (params.shadows != ShadowPass::kAuto) return params.shadows == ShadowPass::kRays;
  return m.in_view / std::max(1, cam.height) >= kShadowRaysPerRow;
}

RenderParams frame_passes(const Scene& scene, const RenderParams& params) {
  RenderParams p = params;
  if (!configuration_iv(params) ||
      (params.visibility != Visibility::kAuto && params.shadows != ShadowPass::kAuto)) {
    return p;
  }
  const CameraFrame cam(scene.camera);
  const Scene tessellated = tessellate_scene(scene, params.tess_tol);
  const PrimitiveSet prims = build_primitives(tessellated);
  const VisibilityMeasure m = measure_visibility(tessellated, prims, cam);
  p.visibility = visibility_by_rays(m, cam, params) ? Visibility::kRays : Visibility::kScanline;
  p.shadows = shadows_by_rays(m, cam, params) ? ShadowPass::kRays : ShadowPass::kVolumes;
  return p;
}

}  // namespace locus
