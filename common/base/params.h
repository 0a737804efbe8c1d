// The render parameters, a band of rows, and the counters of a render: the
// vocabulary every stage, the farm and the CLI share. They name no scene.
#pragma once

#include <cstdint>
#include <string>

#include "common/base/labels.h"
#include "common/base/status.h"

namespace locus {

// METHOD.md §8 configurations: I = raytrace/none, II = local/none,
// III = local/eye, IV = local/eye+shadow; raytrace/eye+shadow is the modern
// BVH baseline.
enum class Method { kRaytrace, kLocal };
enum class Boxes { kNone, kEye, kEyeShadow };
// The names of the CLI's --method and --boxes, and of a job's settings.
inline constexpr Labels<Method, 2> kMethodLabels = {
    {{Method::kRaytrace, "raytrace"}, {Method::kLocal, "local"}}};
inline constexpr Labels<Boxes, 3> kBoxesLabels = {
    {{Boxes::kNone, "none"}, {Boxes::kEye, "eye"}, {Boxes::kEyeShadow, "eye+shadow"}}};

// The local method's visible-surface pass (issue #27; docs/renderer.md
// "Visibility by rays"): the scanline pass of the paper (§3.2), or an eye ray
// per sample; `auto` casts rays for a point-sampled frame crossed by many
// faces per row (common/prepare/visibility.h) and scans otherwise.
// Configuration IV only: II and III always scan.
enum class Visibility { kAuto, kScanline, kRays };
inline constexpr Labels<Visibility, 3> kVisibilityLabels = {
    {{Visibility::kAuto, "auto"}, {Visibility::kScanline, "scanline"}, {Visibility::kRays, "rays"}}};

// How configuration IV finds the shadows of the spans it scans: the shadow
// volumes of the paper (§3.2 step 2, §4.1), or shadow rays through the boxes
// (no volumes are built).
// Both find the same figures on a span (rays by bisection where the
// lights' state changes); rays cost far less where occluders and lights
// are many (docs/renderer.md "Shadows by rays": balls level 5 at --aa 4,
// 2.6x faster and a third of the memory); the paper's scenes are faster
// with volumes. `auto` casts rays where the occluders in view times the
// lights reach 12 per image row (common/prepare/visibility.cpp) and builds
// volumes otherwise.
enum class ShadowPass { kAuto, kVolumes, kRays };
inline constexpr Labels<ShadowPass, 3> kShadowPassLabels = {
    {{ShadowPass::kAuto, "auto"}, {ShadowPass::kVolumes, "volumes"}, {ShadowPass::kRays, "rays"}}};

inline constexpr int kMaxAa = 64;
inline constexpr int kMaxSpp = 64;
// `--tess-tol`: largest screen-space deviation of a tessellated free-form
// surface from the true one, in pixels (docs/tessellation.md).
inline constexpr double kDefaultTessTol = 0.25;

struct RenderParams {
  Method method = Method::kRaytrace;
  Boxes boxes = Boxes::kEyeShadow;
  int spp = 1;  // raytrace: spp x spp stratified samples per pixel; 1 = pixel centre
  // local: multi-scanning with `aa` sub-scanlines per pixel row (paper
  // §3.3); 0 = point sampling at pixel centres.
  int aa = 0;
  int threads = 0;                    // 0 = all cores
  double tess_tol = kDefaultTessTol;  // Bezier surfaces: pixels, > 0
  Visibility visibility = Visibility::kAuto;  // local, configuration IV
  ShadowPass shadows = ShadowPass::kAuto;      // local, configuration IV
};

// Configuration IV (METHOD.md §8), whose own choices are Visibility and
// ShadowPass.
inline bool configuration_iv(const RenderParams& p) {
  return p.method == Method::kLocal && p.boxes == Boxes::kEyeShadow;
}

// The one check of a RenderParams, whoever built it (the CLI, a job from the
// wire): InvalidArgument naming the flag and its allowed values.
Status check_render_params(const RenderParams& params);

// Rows [y0, y1) of the frame.
struct Band {
  int y0 = 0;
  int y1 = 0;
};

// Counters written by `--stats`. Key names are a contract (issue #2): later
// work adds keys but never renames them.
struct Stats {
  double seconds_prepare = 0;
  double seconds_render = 0;
  // CPU time of the rendering threads, summed (a load-independent cost for
  // benchmarks on a shared machine; not carried by the farm).
  double seconds_render_cpu = 0;
  // Cutting Bezier surfaces into triangles, part of seconds_prepare.
  double seconds_tessellate = 0;
  // Reading and checking the scene file, before any frame is prepared:
  // `locus render --workers 0` only (a farm's coordinator loads the scene;
  // not carried by the farm). A large file's load is part of what a frame
  // costs to set up (bench/peers/scaling.py counts it with prepare).
  double seconds_load = 0;
  // Triangles the frame is made of after tessellation (meshes, patch fans
  // and tessellated surfaces). Summing bands or frames keeps the largest.
  uint64_t geometry_triangles = 0;
  uint64_t rays_eye = 0;
  uint64_t rays_reflected = 0;
  uint64_t rays_refracted = 0;
  uint64_t rays_shadow = 0;
  uint64_t tests_ray_object = 0;
  // Configuration IV: point-in-shadow-volume and span-against-volume tests
  // (paper §4.1; docs/shadow-volumes.md).
  uint64_t tests_shadow_volume = 0;
  uint64_t pixels_total = 0;
  uint64_t pixels_ray_traced = 0;  // pixels where an eye, reflected or refracted ray was cast
  uint64_t spans_total = 0;        // local method: visible spans over all rows
  uint64_t spans_ray_traced = 0;   // spans whose pixels were ray traced
  // How shadows were found: "rays" (raytrace; IV where ShadowPass chose
  // rays), "volumes+rays" (II, III: spans by volumes, secondary points by
  // rays), "volumes" (IV).
  std::string shadow_method = "rays";
  // How visible surfaces were found: "scanline" (the local method's pass,
  // paper §3.2) or "rays" (the ray tracer, or the local method where the
  // scene is finer than its pixels: Visibility).
  std::string visibility = "rays";

  Stats& operator+=(const Stats& o);
  std::string to_json() const;
};

}  // namespace locus
