// OBJ meshes through tinyobjloader (obj.h).
#include "common/scene/obj.h"

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <map>
#include <system_error>
#include <utility>
#include <vector>

namespace locus {

Result<Mesh> load_obj(const std::string& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    return InvalidArgument(
        fmt::format("cannot read '{}': no such file (paths are relative to the scene file)", file));
  }
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = std::filesystem::path(file).parent_path().string();
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(file, config)) {
    std::string why = reader.Error();
    while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
    std::replace(why.begin(), why.end(), '\n', ' ');
    return InvalidArgument(fmt::format("cannot load '{}': {}", file, why));
  }
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  bool all_normals = true;
  for (const tinyobj::shape_t& s : reader.GetShapes()) {
    for (const tinyobj::index_t& i : s.mesh.indices)
      all_normals = all_normals && i.normal_index >= 0;
  }
  Mesh m;
  const size_t nv = attrib.vertices.size() / 3, nn = attrib.normals.size() / 3;
  if (!all_normals) {
    for (size_t i = 0; i < nv; ++i) {
      m.positions.emplace_back(attrib.vertices[3 * i], attrib.vertices[3 * i + 1],
                               attrib.vertices[3 * i + 2]);
    }
  }
  std::map<std::pair<int, int>, int> corner_vertex;
  for (const tinyobj::shape_t& s : reader.GetShapes()) {
    const std::vector<tinyobj::index_t>& idx = s.mesh.indices;
    for (size_t k = 0; k + 2 < idx.size(); k += 3) {
      std::array<int, 3> tri{};
      for (int c = 0; c < 3; ++c) {
        const tinyobj::index_t& i = idx[k + c];
        if (i.vertex_index < 0 || static_cast<size_t>(i.vertex_index) >= nv ||
            (all_normals && static_cast<size_t>(i.normal_index) >= nn)) {
          return InvalidArgument(
              fmt::format("'{}': a face refers to a vertex or normal that does not exist", file));
        }
        if (!all_normals) {
          tri[c] = i.vertex_index;
          continue;
        }
        auto [it, inserted] = corner_vertex.emplace(std::pair{i.vertex_index, i.normal_index},
                                                    static_cast<int>(m.positions.size()));
        if (inserted) {
          const size_t v = i.vertex_index, n = i.normal_index;
          m.positions.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1],
                                   attrib.vertices[3 * v + 2]);
          m.normals.emplace_back(attrib.normals[3 * n], attrib.normals[3 * n + 1],
                                 attrib.normals[3 * n + 2]);
        }
        tri[c] = it->second;
      }
      m.triangles.push_back(tri);
    }
  }
  return m;
}

}  // namespace locus
