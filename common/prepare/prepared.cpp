#include "common/prepare/prepared.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "common/base/parallel.h"
#include "common/prepare/hidden_faces.h"
#include "common/prepare/scan_scene.h"
#include "common/prepare/shadow_volume.h"
#include "common/prepare/tessellate.h"
#include "common/prepare/visibility.h"

namespace locus {

CameraFrame::CameraFrame(const Camera& c)
    : from(c.from),
      tan_half(std::tan(glm::radians(c.angle) * 0.5)),
      aspect(static_cast<double>(c.width) / c.height),
      hither(c.hither),
      width(c.width),
      height(c.height) {
  w = glm::normalize(c.at - c.from);
  u = glm::normalize(glm::cross(w, c.up));
  v = glm::cross(u, w);
}

namespace {
// Free-form surfaces become triangles first (METHOD.md §3): everything after
// this sees a mesh.
Scene tessellated(Scene s, const RenderParams& params, double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  Scene out = tessellate_scene(std::move(s), params.tess_tol);
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

// The largest coordinate magnitude of the primitives' boxes, at least 1e-3
// (1 for an empty scene): what the world-scale tolerances are relative to.
double scale_of_world(const std::vector<Aabb>& bounds) {
  Aabb world;
  for (const Aabb& b : bounds) world.extend(b);
  if (world.empty()) return 1.0;
  return std::max({1e-3, max_component(glm::abs(world.lo)), max_component(glm::abs(world.hi))});
}
}  // namespace

PreparedScene::PreparedScene(Scene s, const RenderParams& params)
    : scene(tessellated(std::move(s), params, &seconds_tessellate)),
      camera(scene.camera),
      prims(build_primitives(scene)) {
  // Each stage on the render's threads where it is large enough, its
  // pieces side by side (common/base/parallel.h); the result is the one of
  // one thread.
  const int threads = render_threads(params);
  bvh_for_rays = params.boxes != Boxes::kNone;
  bvh_for_shadows = params.boxes == Boxes::kEyeShadow;
  if (bvh_for_rays || bvh_for_shadows) bvh = build_bvh(prims.bounds, threads);
  for (int j = 0; j < static_cast<int>(scene.lights.size()); ++j)
    emission.push_back(light_emission(scene, j));
  stops_light.reserve(prims.prims.size());
  for (const PrimRef& ref : prims.prims) {
    stops_light.push_back(ref.kind != PrimKind::kCsg &&
                          scene.materials[scene.objects[ref.object].material].t <= 0.0);
  }
  world_scale = scale_of_world(prims.bounds);
  // Secondary rays start this far off the surface: relative to the scene's
  // size, far above double rounding, far below any feature of SPD scenes.
  eps = 1e-9 * std::min(world_scale, 1e7) * 100.0;
  const ClosedSolids solids = closed_convex_solids(prims);
  culls = ray_culls(prims, solids, camera, scan_near_depth(camera, eps), scene.lights, stops_light);
  own_solid = own_solids(prims, solids, scene.lights, stops_light, eps);
  if (bvh_for_rays || bvh_for_shadows) leaf_prims = build_leaf_prims(prims, bvh, stops_light);
  if (!leaf_prims.empty()) {
    leaf_slot.assign(prims.prims.size(), -1);
    for (size_t slot = 0; slot < bvh.order.size(); ++slot)
      leaf_slot[bvh.order[slot]] = static_cast<int>(slot);
  }
  ambient = ambient_intensity(scene);
  if (params.method == Method::kLocal) {
    const VisibilityMeasure measure = measure_visibility(scene, prims, camera);
    by_rays = visibility_by_rays(measure, camera, params);
    if (by_rays) {
      // Finer than the pixels (common/prepare/visibility.h): an eye ray per
      // sample, shadow rays through the boxes; no faces, no volumes.
      scan = std::make_unique<ScanScene>(traced_scan_scene(camera.height, params.aa > 0));
      return;
    }
    scan = std::make_unique<ScanScene>(build_scan_scene(*this, params.aa > 0, threads));
    // The scanline pass finds the shadows of its spans with shadow volumes
    // (paper §3.2 step 2) in configurations II-IV; IV also searches the
    // boxes' volumes for points reached by secondary rays (paper §4.1).
    // Shadows by rays through the boxes instead (ShadowPass): none.
    if (!shadows_by_rays(measure, camera, params)) {
      volumes = std::make_shared<const ShadowVolumes>(
          build_shadow_volumes(*this, bvh_for_shadows, threads));
      point_shadows_by_rays = volumes->search && params.shadows == ShadowPass::kAuto;
    }
  }
}

bool PreparedScene::points_search_volumes() const {
  return volumes && volumes->search && !point_shadows_by_rays;
}

Result<std::shared_ptr<const PreparedScene>> prepare_scene(Scene scene,
                                                           const RenderParams& params) {
  if (Status s = check_render_params(params); !s.ok()) return s;
  if (scene.camera.width < 1 || scene.camera.height < 1) {
    return InvalidArgument("image size must be positive");
  }
  return std::shared_ptr<const PreparedScene>(std::make_shared<PreparedScene>(std::move(scene), params));
}

}  // namespace locus
