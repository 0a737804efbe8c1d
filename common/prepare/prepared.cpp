#include "common/prepare/prepared.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>
#include <variant>

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

SceneGeometry::SceneGeometry(Scene s, const RenderParams& params)
    : scene(tessellated(std::move(s), params, &seconds_tessellate)),
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
  object_material.reserve(scene.objects.size());
  for (const Object& o : scene.objects) object_material.push_back(o.material);
  stops_light.reserve(prims.prims.size());
  for (const PrimRef& ref : prims.prims) {
    stops_light.push_back(ref.kind != PrimKind::kCsg &&
                          scene.materials[object_material[ref.object]].t <= 0.0);
  }
  world_scale = scale_of_world(prims.bounds);
  // Secondary rays start this far off the surface: relative to the scene's
  // size, far above double rounding, far below any feature of SPD scenes.
  eps = 1e-9 * std::min(world_scale, 1e7) * 100.0;
  solids = closed_convex_solids(prims);
  own_solid = own_solids(prims, solids, scene.lights, stops_light, eps);
  if (bvh_for_rays || bvh_for_shadows) leaf_prims = build_leaf_prims(prims, bvh, stops_light);
  if (!leaf_prims.empty()) {
    leaf_slot.assign(prims.prims.size(), -1);
    for (size_t slot = 0; slot < bvh.order.size(); ++slot)
      leaf_slot[bvh.order[slot]] = static_cast<int>(slot);
  }
  ambient = ambient_intensity(scene);
}

PreparedScene::PreparedScene(Scene s, const RenderParams& params)
    : PreparedScene(std::make_shared<const SceneGeometry>(std::move(s), params), params) {}

PreparedScene::PreparedScene(std::shared_ptr<const SceneGeometry> fresh, const RenderParams& params)
    : PreparedScene(fresh, fresh->scene.camera, params) {
  seconds_tessellate = geometry_->seconds_tessellate;
}

PreparedScene::PreparedScene(std::shared_ptr<const SceneGeometry> geometry, const Camera& view,
                             const RenderParams& params)
    : geometry_(std::move(geometry)),
      scene(geometry_->scene),
      camera(view),
      prims(geometry_->prims),
      bvh(geometry_->bvh),
      bvh_for_rays(geometry_->bvh_for_rays),
      bvh_for_shadows(geometry_->bvh_for_shadows),
      emission(geometry_->emission),
      object_material(geometry_->object_material),
      stops_light(geometry_->stops_light),
      own_solid(geometry_->own_solid),
      leaf_prims(geometry_->leaf_prims),
      leaf_slot(geometry_->leaf_slot),
      ambient(geometry_->ambient),
      world_scale(geometry_->world_scale),
      eps(geometry_->eps) {
  // What the camera changes: the faces turned away from the eye, the choice
  // of passes, the scan scene with the curved bodies' bounding polyhedra
  // (paper §3 step ii) and the shadow volumes (step iii).
  const int threads = render_threads(params);
  culls = ray_culls(prims, geometry_->solids, camera, scan_near_depth(camera, eps), scene.lights,
                    stops_light);
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

namespace {

Status check_frame(const Camera& camera, const RenderParams& params) {
  if (Status s = check_render_params(params); !s.ok()) return s;
  if (camera.width < 1 || camera.height < 1) {
    return InvalidArgument("image size must be positive");
  }
  return Status::Ok();
}

// Whether every frame of `source`'s animation has the geometry of the first:
// only the camera moves (keys, --orbit, the image size), and no surface is
// cut into triangles for the view.
bool geometry_stands_still(const Scene& source) {
  if (!source.animation.objects.empty() || !source.animation.lights.empty()) return false;
  return std::none_of(source.objects.begin(), source.objects.end(), [](const Object& o) {
    return std::holds_alternative<BezierSurface>(o.shape);
  });
}

}  // namespace

Result<std::shared_ptr<const PreparedScene>> prepare_scene(Scene scene,
                                                           const RenderParams& params) {
  if (Status s = check_frame(scene.camera, params); !s.ok()) return s;
  return std::shared_ptr<const PreparedScene>(std::make_shared<PreparedScene>(std::move(scene), params));
}

AnimationGeometry::AnimationGeometry(const Scene& source) : still_(geometry_stands_still(source)) {}

Result<std::shared_ptr<const PreparedScene>> AnimationGeometry::prepare(const Camera& view,
                                                                        FunctionRef<Scene()> frame,
                                                                        const RenderParams& params,
                                                                        bool* reused) {
  if (reused) *reused = false;
  if (!still_) return prepare_scene(frame(), params);
  std::shared_ptr<const SceneGeometry> geometry;
  {
    std::lock_guard lk(mu_);
    // The hierarchy is built or not by --boxes; no other setting changes
    // the geometry (tess_tol cuts no surface here).
    if (geometry_ && boxes_ == params.boxes) geometry = geometry_;
  }
  if (!geometry) {
    auto prepared = prepare_scene(frame(), params);
    if (!prepared.ok()) return prepared;
    std::lock_guard lk(mu_);
    geometry_ = (*prepared)->geometry();
    boxes_ = params.boxes;
    return prepared;
  }
  if (Status st = check_frame(view, params); !st.ok()) return st;
  if (reused) *reused = true;
  return std::shared_ptr<const PreparedScene>(
      std::make_shared<PreparedScene>(std::move(geometry), view, params));
}

}  // namespace locus
