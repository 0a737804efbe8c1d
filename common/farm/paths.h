// Paths that a peer names, confined to the roots the operator chose: a
// scene can never make a worker read, nor a job make the coordinator write,
// outside them (docs/farm.md "Security"). The renderer's loaders in common/
// resolve whatever path they are given; the farm confines at its boundary,
// before a scene from the wire reaches them.
#pragma once

#include <filesystem>
#include <string>

#include "common/base/status.h"
#include "common/scene/scene.h"

namespace locus {
namespace v1 {
class Scene;
}

namespace farm {

// Refuses an empty path, control characters and any `..` component (even
// one that would stay inside): InvalidArgument naming `what`.
Status check_no_parent_refs(const std::string& path, const std::string& what);

// `path` confined under `root`: a relative path is taken under the root;
// an absolute one must lie inside it. No `..` component; and once the
// existing part is resolved (symlinks followed) it must still be inside
// the root's resolved form. Returns the resolved path.
Result<std::filesystem::path> confine_path(const std::filesystem::path& root,
                                           const std::string& path, const std::string& what);

// Every objects[i].mesh.obj of a scene from the wire, confined under
// `mesh_root` and rewritten to the resolved path. With no mesh root, a
// scene must carry its meshes inline and any obj reference is refused.
// `name` starts each message ("scene.json: objects[2].mesh.obj: ...").
Status confine_mesh_paths(v1::Scene& scene, const std::string& mesh_root, const std::string& name);

// A scene that came over the wire, converted (scene_from_proto) with its
// mesh paths confined as above. The message is copied only where an object
// names an OBJ file: a big scene of inline polygons (SPD tetra level 9:
// 262,144 objects) is converted as it came.
Result<Scene> scene_from_wire(const v1::Scene& scene, const std::string& mesh_root,
                              const std::string& name);

// A file name received from a coordinator (FetchResults) before a client
// writes it: one plain path component, nothing else.
Status check_plain_file_name(const std::string& name, const std::string& what);

}  // namespace farm
}  // namespace locus
