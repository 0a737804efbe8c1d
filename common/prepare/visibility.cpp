#include "common/prepare/visibility.h"

#include <algorithm>
#include <cmath>

#include "common/prepare/prepared.h"
#include "common/prepare/tessellate.h"

namespace locus {

VisibilityMeasure measure_visibility(const Scene& scene, const PrimitiveSet& prims,
                                     const CameraFrame& cam) {
  VisibilityMeasure m;
  m.lights = static_cast<int>(scene.lights.size());
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
// Shadow volumes pay per occluder and light: each occluder's volume is
// built for every light and tested wherever it covers a span, exactly
// (paper §3.2 step 2). Rays pay per sample: a ray to each light from each
// pixel's piece of a span, and bisection where the lights' state changes
// (sub_line.cpp figures_by_rays), which finds the same figures as the
// volumes' intervals, so both give the same image to within where a shadow
// narrower than a pixel falls between two samples. The choice is then one
// of time alone. Measured side by side at --aa 4, one thread, on the SPD
// scenes (levels 2 and 3) and the paper's, at 256x256 and 512x512
// (docs/renderer.md "Shadows by rays"), the volumes' time over the rays'
// grows with the occluders in view per row and with the lights. Counted
// as occluders in view times lights per row (M), session 24 found it
// passing 1 between 9 and 16 and cast rays from 12. Shadow rays have
// become cheaper since (the 8-wide walk, back faces and the receiver's own
// solid skipped, culls read before the leaf copies), and session 33's
// measurement of 50 such frames moved the crossing down: teapot 1.25
// at 9.0, gears level 2 1.40 and sombrero level 2 1.14 at 11.3, tetra
// 1.02 at 8.2, all faster by rays; below 8, sombrero 1.07 at 5.5 (and
// 0.67 at 2.8), the level-2 scenes below 4 0.41-1.11, the paper's scenes
// 0.59-0.91. So rays from 8: the worst choice left on those frames is
// level 2 teapot at 256x256 (volumes, 1.11x the rays' time), where at 12
// it was gears level 2 at 512x512 (1.40x).
constexpr double kShadowRayOccluderLightsPerRow = 8;
}  // namespace

bool shadows_by_rays(const VisibilityMeasure& m, const CameraFrame& cam,
                     const RenderParams& params) {
  if (!configuration_iv(params)) return false;
  if (params.shadows != ShadowPass::kAuto) return params.shadows == ShadowPass::kRays;
  return m.in_view * std::max(1, m.lights) / std::max(1, cam.height) >=
         kShadowRayOccluderLightsPerRow;
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
