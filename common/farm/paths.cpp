#include "common/farm/paths.h"

#include <algorithm>

#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus::farm {
namespace fs = std::filesystem;

Status check_no_parent_refs(const std::string& path, const std::string& what) {
  if (path.empty()) return InvalidArgument(what + ": the path is empty");
  if (std::any_of(path.begin(), path.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; }))
    return InvalidArgument(what + ": the path contains control characters");
  for (const fs::path& part : fs::path(path)) {
    if (part == "..") {
      return InvalidArgument(what + " '" + path +
                             "': '..' is not allowed (paths stay inside their root)");
    }
  }
  return Status::Ok();
}

Result<fs::path> confine_path(const fs::path& root, const std::string& path,
                              const std::string& what) {
  if (Status s = check_no_parent_refs(path, what); !s.ok()) return s;
  std::error_code ec;
  const fs::path base = fs::weakly_canonical(fs::absolute(root, ec), ec);
  if (ec || root.empty()) return FailedPrecondition(what + ": the root directory is not usable");
  const fs::path given(path);
  const fs::path joined = given.is_absolute() ? given : base / given;
  const fs::path resolved = fs::weakly_canonical(joined, ec);
  if (ec) return InvalidArgument(what + " '" + path + "': cannot resolve: " + ec.message());
  // Component-wise prefix: /srv/root2 is not inside /srv/root.
  auto [r, p] = std::mismatch(base.begin(), base.end(), resolved.begin(), resolved.end());
  if (r != base.end()) {
    return InvalidArgument(what + " '" + path + "': outside the allowed root " + base.string() +
                           (given.is_absolute() ? "" : " (a symbolic link leads out of it)"));
  }
  return resolved;
}

Status confine_mesh_paths(v1::Scene& scene, const std::string& mesh_root,
                          const std::string& name) {
  for (int i = 0; i < scene.objects_size(); ++i) {
    if (!scene.objects(i).has_mesh() || scene.objects(i).mesh().obj().empty()) continue;
    const std::string what = name + ": objects[" + std::to_string(i) + "].mesh.obj";
    if (mesh_root.empty()) {
      return InvalidArgument(what +
                             ": a scene sent to the farm must carry its meshes inline (no mesh "
                             "root is configured for OBJ files, --mesh-root)");
    }
    auto p = confine_path(mesh_root, scene.objects(i).mesh().obj(), what);
    if (!p.ok()) return p.status();
    scene.mutable_objects(i)->mutable_mesh()->set_obj(p->string());
  }
  return Status::Ok();
}

Result<Scene> scene_from_wire(const v1::Scene& scene, const std::string& mesh_root,
                              const std::string& name) {
  const bool names_files =
      std::any_of(scene.objects().begin(), scene.objects().end(),
                  [](const v1::Object& o) { return o.has_mesh() && !o.mesh().obj().empty(); });
  if (!names_files) return scene_from_proto(scene, name);
  v1::Scene confined = scene;
  if (Status s = confine_mesh_paths(confined, mesh_root, name); !s.ok()) return s;
  return scene_from_proto(confined, name);
}

Status check_plain_file_name(const std::string& name, const std::string& what) {
  if (name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos ||
      std::any_of(name.begin(), name.end(), [](unsigned char c) { return c < 0x20 || c == 0x7f; })) {
    return InvalidArgument(what + ": '" + name + "' is not a plain file name");
  }
  return Status::Ok();
}

}  // namespace locus::farm
