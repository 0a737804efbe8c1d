// load_scene: the loader by file extension (scene_io.h).
#include "common/scene/scene_io.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <filesystem>

namespace locus {

Result<Scene> load_scene(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".nff") return load_nff(path);
  if (ext == ".json") return load_scene_json(path);
  return InvalidArgument(
      fmt::format("{}: unknown scene format '{}' (expected a .nff file or a .json scene, "
                  "docs/scene-format.md)",
                  path, ext.empty() ? "no extension" : ext));
}

}  // namespace locus
