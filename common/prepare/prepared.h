// PreparedScene: everything derived from a scene before its rows are
// rendered. Built once per frame, shared read-only by threads and bands.
#pragma once

#include <memory>
#include <mutex>
#include <vector>

#include "common/base/function_ref.h"
#include "common/base/params.h"
#include "common/geometry/bvh.h"
#include "common/geometry/geometry.h"
#include "common/geometry/leaf_prims.h"
#include "common/prepare/hidden_faces.h"
#include "common/prepare/scan_scene.h"
#include "common/scene/scene.h"

namespace locus {

struct ShadowVolumes;  // common/prepare/shadow_volume.h

// SHADING.md "Camera and pixels".
struct CameraFrame {
  Vec3 from, u, v, w;
  double tan_half = 0, aspect = 1, hither = 0;
  int width = 0, height = 0;

  explicit CameraFrame(const Camera& c);
  // Unit direction of the point sample at image coordinates (x, y).
  Vec3 direction(double x, double y) const {
    return glm::normalize(w + (2.0 * x / width - 1.0) * tan_half * aspect * u +
                          (1.0 - 2.0 * y / height) * tan_half * v);
  }
  // Image coordinates (x right, y down, in pixels) of a point in front of
  // the eye: direction() inverted.
  Vec2 project(const Vec3& p) const {
    const Vec3 q = p - from;
    const double zc = glm::dot(q, w);
    return Vec2(0.5 * width * (1.0 + glm::dot(q, u) / (zc * tan_half * aspect)),
                0.5 * height * (1.0 - glm::dot(q, v) / (zc * tan_half)));
  }
};

// The part of a frame's preparation that its camera does not change: the
// scene with its free-form surfaces cut into triangles, its primitives and
// their hierarchy of boxes (paper §3 step ii), and what is found on them once
// for every view. The frames of an animation whose objects and lights stand still
// share one (AnimationGeometry below; docs/renderer.md "Frames that share
// their geometry").
struct SceneGeometry {
  SceneGeometry(Scene s, const RenderParams& params);

  double seconds_tessellate = 0;  // set first: the scene below is tessellated
  // Bezier surfaces already cut into meshes. Its camera is the frame's that
  // built it: a frame's own is PreparedScene::camera.
  Scene scene;
  PrimitiveSet prims;
  Bvh bvh;
  bool bvh_for_rays = true;     // eye, reflected and refracted rays
  bool bvh_for_shadows = true;  // shadow rays
  std::vector<Color> emission;  // per light, resolved
  // Per scene.objects[i]: its material's index, side by side (an Object,
  // with its transform and names, spans several cache lines; on SPD tetra
  // level 9 each of 262,144 faces is an object of its own).
  std::vector<int> object_material;
  // Per prims[i]: 1 where a shadow ray that crosses the primitive is
  // stopped by it whatever else it crosses (eq. (2)): not CSG, and its
  // object's material transmits nothing.
  std::vector<uint8_t> stops_light;
  // The closed convex solids made of polygons (hidden_faces.h).
  ClosedSolids solids;
  // Per prims[i]: the closed solid a shadow ray from it need not search
  // (own_solid_skip, hidden_faces.h); empty where no face has one.
  std::vector<OwnSolid> own_solid;
  // Small polygons, triangles, spheres and cones in the hierarchy's leaf
  // order, for the ray walk (leaf_prims.h); empty where there are none or
  // no hierarchy.
  std::vector<LeafPrim> leaf_prims;
  // Per prims[i]: its slot in the hierarchy's leaf order (bvh.order), for
  // the searches that meet primitives outside the walk (the shadow volumes'
  // exact tests, the eye candidates); empty with leaf_prims.
  std::vector<int> leaf_slot;
  double ambient = 0;
  // The world's scale, once for every tolerance relative to it: the largest
  // coordinate magnitude of the primitives' boxes, at least 1e-3 (1 for an
  // empty scene).
  double world_scale = 1.0;
  // Offset of secondary ray origins: 1e-7 of world_scale (capped at 1e7).
  double eps = 1e-9;
};

class PreparedScene {
 public:
  PreparedScene(Scene s, const RenderParams& params);
  // A frame seen by `camera` of a geometry built for another frame of the
  // same animation, with the same settings (AnimationGeometry): only what
  // the camera changes is made.
  PreparedScene(std::shared_ptr<const SceneGeometry> geometry, const Camera& view,
                const RenderParams& params);

 private:
  // A frame of the geometry just built for it (its camera, its tessellation).
  PreparedScene(std::shared_ptr<const SceneGeometry> fresh, const RenderParams& params);
  // First: the references below are into it.
  std::shared_ptr<const SceneGeometry> geometry_;

 public:
  const std::shared_ptr<const SceneGeometry>& geometry() const { return geometry_; }
  // This frame's tessellation: 0 where its geometry was built before.
  double seconds_tessellate = 0;
  const Scene& scene;  // SceneGeometry::scene (its camera is not this frame's)
  CameraFrame camera;
  const PrimitiveSet& prims;
  const Bvh& bvh;
  const bool& bvh_for_rays;
  const bool& bvh_for_shadows;
  const std::vector<Color>& emission;
  const std::vector<int>& object_material;
  // The material of scene object `object` (SceneGeometry::object_material).
  const Material& material_of(int object) const { return scene.materials[object_material[object]]; }
  const std::vector<uint8_t>& stops_light;
  // Per prims[i]: which rays may skip it, a back face of a closed convex
  // solid (ray_culls, hidden_faces.h: kCullEye, cull_light(j)).
  std::vector<uint8_t> culls;
  const std::vector<OwnSolid>& own_solid;
  const std::vector<LeafPrim>& leaf_prims;
  const std::vector<int>& leaf_slot;
  // Primitive `prim`'s slot in leaf_prims, or -1 where none are kept.
  int leaf_slot_of(int prim) const { return leaf_slot.empty() ? -1 : leaf_slot[prim]; }
  // The leaf copy in slot `slot`, or null (no slot, or a kind not copied).
  const LeafPrim* leaf_prim_at(int slot) const {
    if (slot < 0 || leaf_prims.empty()) return nullptr;
    const LeafPrim& lp = leaf_prims[slot];
    return lp.kind != LeafKind::kOther ? &lp : nullptr;
  }
  // The leaf copy of primitive `prim`, or null.
  const LeafPrim* leaf_prim_of(int prim) const { return leaf_prim_at(leaf_slot_of(prim)); }
  const double& ambient;
  const double& world_scale;
  const double& eps;
  std::unique_ptr<ScanScene> scan;  // the local method's faces (--method local)
  // The local method finds visible surfaces by eye rays: `scan` has no
  // faces and traces everything, `volumes` is empty (Visibility::kRays).
  bool by_rays = false;
  // Configuration IV (--method local --boxes eye+shadow): shadow volumes
  // replace shadow rays (paper §4.1).
  std::shared_ptr<const ShadowVolumes> volumes;
  // Configuration IV with --shadows auto, where the spans' shadows are the
  // volumes': a point reached by a secondary ray, or sampled inside a
  // curved body's span, casts shadow rays through the boxes instead of
  // searching the volumes' hierarchy (paper §4.1's point test). The
  // answers are the same; a point has no span's coherence to share, and
  // its ray costs less than its search on the frames measured
  // (docs/renderer.md "Points by rays"). --shadows volumes keeps the
  // paper's search.
  bool point_shadows_by_rays = false;
  // Whether a point without a span finds its shadows by searching the
  // volumes' hierarchy (volume_transmittance; paper §4.1), not by rays.
  bool points_search_volumes() const;
};

// The geometry the frames of one animation share. Where its objects and
// lights have no keys and it has no free-form surface (whose triangles are
// cut for the view: tessellate.h), two frames differ only in their camera,
// and the second is prepared on the first's SceneGeometry. Otherwise every
// frame is prepared afresh. Safe to use from several threads.
class AnimationGeometry {
 public:
  // `source`: the scene before any frame's animation is applied.
  explicit AnimationGeometry(const Scene& source);
  // prepare_scene() for the frame whose camera is `view`: on an earlier
  // frame's geometry where one serves, otherwise on the frame's whole scene,
  // which `frame` makes (the source at that frame: farm::frame_scene).
  // `reused`, if given: whether an earlier frame's geometry served.
  Result<std::shared_ptr<const PreparedScene>> prepare(const Camera& view,
                                                       FunctionRef<Scene()> frame,
                                                       const RenderParams& params,
                                                       bool* reused = nullptr);
  // Whether its frames share their geometry.
  bool shared() const { return still_; }
  // Lets the geometry go (its memory, once no prepared frame holds it); the
  // next frame is prepared afresh.
  void release() {
    std::lock_guard lk(mu_);
    geometry_.reset();
  }

 private:
  bool still_ = false;
  std::mutex mu_;
  std::shared_ptr<const SceneGeometry> geometry_;
  Boxes boxes_ = Boxes::kNone;  // the setting geometry_ was built with
};

// The paper's §3 steps ii-iii for one frame: tessellation, primitives and
// their hierarchy of boxes, the scan scene and the shadow volumes. Checks
// `params` first (check_render_params) and the image size.
// `scene` by value: a caller done with it moves it in (a big mesh is then
// never copied).
Result<std::shared_ptr<const PreparedScene>> prepare_scene(Scene scene,
                                                           const RenderParams& params);

}  // namespace locus
