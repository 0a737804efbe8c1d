// The native scene format: proto/scene.proto read as JSON
// (docs/scene-format.md). The entry points only: the syntax check is in
// json_syntax.cpp, the conversion to the scene in scene_proto.cpp, OBJ
// meshes in obj.cpp.
#include <google/protobuf/util/json_util.h>

#include <filesystem>
#include <string>
#include <string_view>

#include "common/scene/json_syntax.h"
#include "common/scene/scene_io.h"
#include "common/scene/validate.h"
#include "proto/scene.pb.h"

namespace locus {

Result<Scene> parse_scene_json(std::string_view text, const std::string& name,
                               const std::string& base_dir) {
  if (std::string error = json_syntax_error(text); !error.empty()) {
    return InvalidArgument(name.empty() ? error : name + ":" + error);  // file:line:col
  }
  v1::Scene proto;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = false;  // a misspelt field is an error, not a default
  const auto status = google::protobuf::util::JsonStringToMessage(
      google::protobuf::StringPiece(text.data(), text.size()), &proto, options);
  if (!status.ok()) {
    const std::string what = rewrite_protobuf_error(status.message().as_string());
    return InvalidArgument(name.empty() ? what : name + ": " + what);
  }
  return scene_from_proto(proto, name, base_dir);
}

Result<Scene> load_scene_json(const std::string& path) {
  Result<std::string> text = read_text_file(path);
  if (!text.ok()) return text.status();
  return parse_scene_json(*text, path, std::filesystem::path(path).parent_path().string());
}

}  // namespace locus
