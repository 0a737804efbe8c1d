// OBJ meshes for the native scene format: a JSON object's "mesh": {"obj":
// "file.obj"} (scene_proto.cpp resolves the path against the scene file's
// folder and names the JSON path in messages).
#pragma once

#include <string>

#include "common/base/status.h"
#include "common/scene/scene.h"

namespace locus {

// A triangulated OBJ file (tinyobjloader) as a Mesh. Normals are kept only
// when every corner has one; a vertex is then a distinct (position, normal)
// pair. An error names the file and what is wrong with it.
Result<Mesh> load_obj(const std::string& file);

}  // namespace locus
