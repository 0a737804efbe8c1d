// Free-form surfaces (METHOD.md §3): bicubic Bezier patches cut into
// triangles at prepare time, per frame, exactly as finely as the image needs.
// The scanline pass and the ray tracer then see an ordinary triangle mesh.
//
// docs/tessellation.md has the scheme: a uniform grid per patch whose rates
// bound the screen-space deviation by the control net's second differences,
// boundary rows shared between neighbouring patches (so no cracks), and
// coarse rates for patches nobody sees directly.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "common/base/math.h"
#include "common/scene/scene.h"

namespace locus {

// Segments per patch side: a patch cut by the eye plane could ask for any
// number; this caps it (docs/tessellation.md "Limits").
inline constexpr int kMaxTessRate = 256;
// Triangles one surface may become: beyond it every rate is scaled down
// alike (the tolerance is then not met), so a scene cannot exhaust a
// worker's memory with patches seen from very close.
inline constexpr int64_t kMaxTessTriangles = int64_t{1} << 24;

// Patches that neither the eye nor a mirror or glass can show (outside the
// view frustum or behind hither, in a scene without ks > 0 or t > 0) are cut
// to this many times the tolerance, judged at their distance from the eye:
// enough for the shadows they cast into the view, far fewer triangles.
inline constexpr double kOffscreenTolFactor = 16.0;

// Point and unit normal of a patch at (u, v) in [0, 1]^2.
Vec3 bezier_point(const BezierPatch& p, double u, double v);
// The direction of dS/du x dS/dv. Where that vanishes (a boundary row
// collapsed to a point, as at the Utah teapot's lid knob and bottom), the
// limit from inside the patch; (0, 0, 1) only for a patch with no area.
Vec3 bezier_normal(const BezierPatch& p, double u, double v);

// How the camera of a frame sees world space (SHADING.md camera).
struct TessView {
  Vec3 eye{0, 0, 0}, u{1, 0, 0}, v{0, 1, 0}, w{0, 0, -1};
  double tan_half = 1, aspect = 1, hither = 0;
  int height = 1;
  double tolerance = 0.25;  // pixels
  // The scene holds a mirror or glass (ks > 0 or t > 0): any patch may be
  // seen in it, so none is cut coarsely.
  bool mirrors = false;
  int64_t max_triangles = kMaxTessTriangles;  // per surface
};
TessView make_tess_view(const Scene& scene, double tolerance);

// How finely one patch is cut: pixels of screen deviation per world unit of
// deviation from the surface (a bound over the patch), and whether the eye
// sees the patch directly.
struct PatchScale {
  double pixels_per_unit = 0;
  bool in_view = false;
};
PatchScale patch_scale(const TessView& view, const BezierPatch& world_patch);

// Segments along u and v for a patch seen at `pixels_per_unit`, so that every
// triangle deviates from the surface by at most `tolerance` pixels.
std::array<int, 2> patch_rates(const BezierPatch& world_patch, double pixels_per_unit,
                               double tolerance);

// One surface cut into triangles, in world space.
struct SurfaceTessellation {
  Mesh mesh;                              // positions, analytic normals, triangles (u x v front)
  std::vector<Vec2> uv;                   // per vertex: its parameters on its patch
  std::vector<int> vertex_patch;          // per vertex: its patch
  std::vector<std::array<int, 2>> rates;  // per patch: the interior grid's (nu, nv)
};
SurfaceTessellation tessellate_surface(const std::vector<BezierPatch>& world_patches,
                                       const TessView& view);

// The scene with every BezierSurface replaced by its tessellation: a Mesh in
// world space (identity transform), same material, name and origin.
// Depends only on the scene (its camera included) and the tolerance, so
// every band and every farm worker gets the same triangles.
Scene tessellate_scene(Scene scene, double tolerance);

}  // namespace locus
