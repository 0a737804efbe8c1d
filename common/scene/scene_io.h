// Scene loaders (NFF and the native JSON format), the proto conversion used
// on the wire, and semantic validation. Every error names the input: the
// file, then the line (NFF) or the JSON path, what is wrong and the expected
// form. A Status carrying several problems has one per line.
//
// Where they live: load_scene in scene_io.cpp; NFF in nff.cpp; the JSON
// entry points in scene_json.cpp, which run json_syntax.cpp's check, then
// protobuf's parser, then scene_proto.cpp's conversion (OBJ meshes through
// obj.cpp); validate_scene in validate.cpp.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/base/status.h"
#include "common/scene/scene.h"

namespace locus {
namespace v1 {
class Scene;
}

// Largest accepted image side, in pixels (docs/scene-format.md).
inline constexpr int kMaxResolution = 16384;

// By extension: .nff, or .json (native format).
Result<Scene> load_scene(const std::string& path);

Result<Scene> load_nff(const std::string& path);
Result<Scene> parse_nff(std::string_view text, const std::string& name);

Result<Scene> load_scene_json(const std::string& path);
// base_dir resolves relative OBJ paths.
Result<Scene> parse_scene_json(std::string_view text, const std::string& name,
                               const std::string& base_dir);

// The wire form. scene_to_proto writes meshes inline and transforms as
// matrices, so scene_from_proto(scene_to_proto(s)) renders identically.
v1::Scene scene_to_proto(const Scene& scene);
Result<Scene> scene_from_proto(const v1::Scene& proto, const std::string& name,
                               const std::string& base_dir = "");

// Semantic checks shared by every loader: non-finite numbers, radii <= 0,
// degenerate or non-planar polygons, ior < 1, coefficients out of range,
// missing camera, zero or oversized resolution, bad indices. Each problem is
// "<origin>: <field>: <what>, <expected>".
std::vector<std::string> validate_scene(const Scene& scene);

}  // namespace locus
