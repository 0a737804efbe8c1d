// The worker's rendering logic, without a network: scenes cached by content
// hash, the prepared frame of the last few (scene, frame) pairs reused across
// that frame's bands, and one band rendered through render_band().
#pragma once

#include <atomic>
#include <list>
#include <map>
#include <memory>
#include <string>

#include "common/farm/types.h"
#include "common/render.h"
#include "common/scene/scene.h"

namespace locus {
namespace v1 {
class Scene;
}

namespace farm {

class BandRenderer {
 public:
  // `threads` per band (0 = all cores); OBJ files a scene names are read
  // from under `mesh_root` only (empty: none, meshes inline); the cache
  // sizes bound memory.
  explicit BandRenderer(int threads, std::string mesh_root = "", size_t max_scenes = 4,
                        size_t max_prepared = 2);

  bool has_scene(const std::string& hash) const { return scenes_.count(hash) != 0; }
  // Converts and keeps a scene received from the coordinator; its mesh
  // paths confined under the mesh root (common/farm/paths.h).
  Status add_scene(const std::string& hash, const v1::Scene& scene, const std::string& name);
  // The same for a serialized scene (GetSceneResponse.scene).
  Status add_scene_bytes(const std::string& hash, const std::string& bytes,
                         const std::string& name);
  // Renders the leased band; its scene must have been added. The returned
  // output carries pixels and stats (ids are the caller's): the pixels in
  // the lease's encoding (`encoded`), or as floats (`rgb`) when it asks for
  // float32.
  // `abandon`, if given, is render_band's cancellation flag: once set (the
  // lease was revoked or handed back), the band stops within a row and the
  // result is Cancelled.
  Result<BandOutput> render(const BandLease& band, const std::atomic<bool>* abandon = nullptr);

  size_t scenes_held() const { return scenes_.size(); }
  int prepares() const { return prepares_; }
  // Of those, the frames prepared on an earlier frame's geometry.
  int geometry_reuses() const { return geometry_reuses_; }

 private:
  struct Prepared {
    std::string key;
    std::string scene_hash;
    std::shared_ptr<const PreparedScene> scene;
  };
  int threads_;
  std::string mesh_root_;
  size_t max_scenes_;
  size_t max_prepared_;
  struct Held {
    std::shared_ptr<const Scene> scene;
    // Its frames' shared geometry, where they differ only in their camera.
    std::unique_ptr<AnimationGeometry> geometry;
  };
  std::map<std::string, Held> scenes_;
  std::list<std::string> scene_order_;  // least recently added first
  std::list<Prepared> prepared_;        // most recently used first
  int prepares_ = 0;
  int geometry_reuses_ = 0;
};

}  // namespace farm
}  // namespace locus
