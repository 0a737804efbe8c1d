// PreparedScene: everything derived from a scene before its rows are
// rendered. Built once per frame, shared read-only by threads and bands.
#pragma once

#include <memory>
#include <vector>

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

class PreparedScene {
 public:
  PreparedScene(Scene s, const RenderParams& params);

  double seconds_tessellate = 0;  // set first: the scene below is tessellated
  Scene scene;                    // Bezier surfaces already cut into meshes
  CameraFrame camera;
  PrimitiveSet prims;
  Bvh bvh;
  bool bvh_for_rays = true;     // eye, reflected and refracted rays
  bool bvh_for_shadows = true;  // shadow rays
  std::vector<Color> emission;  // per light, resolved
  // Per prims[i]: 1 where a shadow ray that crosses the primitive is
  // stopped by it whatever else it crosses (eq. (2)): not CSG, and its
  // object's material transmits nothing.
  std::vector<uint8_t> stops_light;
  // Per prims[i]: which rays may skip it, a back face of a closed convex
  // solid (ray_culls, hidden_faces.h: kCullEye, cull_light(j)).
  std::vector<uint8_t> culls;
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
  double ambient = 0;
  // The world's scale, once for every tolerance relative to it: the largest
  // coordinate magnitude of the primitives' boxes, at least 1e-3 (1 for an
  // empty scene).
  double world_scale = 1.0;
  // Offset of secondary ray origins: 1e-7 of world_scale (capped at 1e7).
  double eps = 1e-9;
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

// The paper's §3 steps ii-iii for one frame: tessellation, primitives and
// their hierarchy of boxes, the scan scene and the shadow volumes. Checks
// `params` first (check_render_params) and the image size.
// `scene` by value: a caller done with it moves it in (a big mesh is then
// never copied).
Result<std::shared_ptr<const PreparedScene>> prepare_scene(Scene scene,
                                                           const RenderParams& params);

}  // namespace locus
