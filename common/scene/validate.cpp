// Semantic checks of a scene, whatever loader built it (scene_io.h,
// validate.h). Limits and tolerances are documented in docs/scene-format.md.
#include "common/scene/validate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <sstream>
#include <utility>

#include "common/scene/animation.h"
#include "common/scene/scene_io.h"

namespace locus {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

std::string indexed(const char* field, size_t i) { return fmt::format("{}[{}]", field, i); }


double bbox_diagonal(const std::vector<Vec3>& v) {
  if (v.empty()) return 0.0;
  Vec3 lo = v[0], hi = v[0];
  for (const Vec3& p : v) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  return glm::length(hi - lo);
}

void check_finite(const Vec3& v, const std::string& field, Problems& out) {
  if (!is_finite(v)) out.push_back({field, "must be finite, got " + format_vec(v)});
}

void check_finite_list(const std::vector<Vec3>& v, const char* field, Problems& out) {
  // The field's name is written only for a problem (not once per vertex).
  for (size_t i = 0; i < v.size(); ++i) {
    if (!is_finite(v[i])) check_finite(v[i], indexed(field, i), out);
  }
}

// A closed interval [lo, hi]; NaN fails every comparison and lands here too.
void check_range(double x, double lo, double hi, const std::string& field, Problems& out) {
  if (!(x >= lo && x <= hi)) {
    out.push_back({field, fmt::format("must be in [{}, {}], got {}", lo, hi, format_number(x))});
  }
}

void check_at_least(double x, double lo, const std::string& field, Problems& out) {
  if (!(x >= lo && is_finite(x))) {
    out.push_back(
        {field, fmt::format("must be a finite number >= {}, got {}", lo, format_number(x))});
  }
}

void check_color(const Color& c, const std::string& field, Problems& out) {
  if (!is_finite(c) || min_component(c) < 0.0) {
    out.push_back({field, "must be finite and >= 0 in every channel, got " + format_vec(c)});
  }
}

void check_normals(const std::vector<Vec3>& normals, Problems& out) {
  for (size_t i = 0; i < normals.size(); ++i) {
    if (!is_finite(normals[i])) {
      check_finite(normals[i], indexed("normals", i), out);
    } else if (glm::length(normals[i]) == 0.0) {
      out.push_back({indexed("normals", i), "must not be zero"});
    }
  }
}

Problems check(const Sphere& s) {
  Problems out;
  check_finite(s.center, "center", out);
  if (!(s.radius > 0.0 && is_finite(s.radius))) {
    out.push_back({"radius", "must be positive, got " + format_number(s.radius)});
  }
  return out;
}

Problems check(const Cone& c) {
  Problems out;
  check_finite(c.base, "base", out);
  check_finite(c.apex, "apex", out);
  bool radii_ok = true;
  for (auto [r, field] :
       {std::pair{c.base_radius, "base_radius"}, {c.apex_radius, "apex_radius"}}) {
    if (!(r >= 0.0 && is_finite(r))) {
      out.push_back({field, "must not be negative, got " + format_number(r)});
      radii_ok = false;
    }
  }
  if (radii_ok && c.base_radius == 0.0 && c.apex_radius == 0.0) {
    out.push_back({"", "base_radius and apex_radius are both 0; at least one must be positive"});
  }
  if (is_finite(c.base) && is_finite(c.apex) && c.base == c.apex) {
    out.push_back(
        {"", "base and apex coincide at " + format_vec(c.base) + "; the axis needs a length"});
  }
  return out;
}

// A convex polyhedron: every face a planar polygon running counter-clockwise
// seen from outside, every vertex behind every face plane (convex, outward
// faces), every edge shared by exactly two faces in opposite directions
// (closed). The renderer turns the faces into half-spaces, so an inward or
// missing face would silently change the solid.
Problems check(const Polyhedron& p) {
  Problems out;
  check_finite_list(p.vertices, "vertices", out);
  if (!out.empty()) return out;
  if (p.vertices.size() < 4 || p.faces.size() < 4) {
    out.push_back({"", fmt::format("needs at least 4 vertices and 4 faces, got {} and {}",
                                   p.vertices.size(), p.faces.size())});
    return out;
  }
  const int n = static_cast<int>(p.vertices.size());
  bool indices_ok = true;
  for (size_t f = 0; f < p.faces.size(); ++f) {
    for (int i : p.faces[f]) {
      if (i < 0 || i >= n) {
        out.push_back(
            {indexed("faces", f), fmt::format("vertex index {} out of range [0, {})", i, n)});
        indices_ok = false;
      }
    }
  }
  if (!indices_ok) return out;

  const double size = bbox_diagonal(p.vertices);
  std::map<std::pair<int, int>, size_t> edge_face;
  for (size_t f = 0; f < p.faces.size(); ++f) {
    const std::vector<int>& face = p.faces[f];
    std::vector<Vec3> loop;
    for (int i : face) loop.push_back(p.vertices[i]);
    Problems face_problems = check_polygon(loop);
    if (!face_problems.empty()) {
      for (Problem& fp : face_problems) {
        out.push_back({indexed("faces", f), fp.field.empty() ? fp.what : fp.field + " " + fp.what});
      }
      continue;
    }
    const Vec3 normal = glm::normalize(newell_vector(loop));
    const double offset = glm::dot(normal, loop[0]);
    for (int i = 0; i < n; ++i) {
      if (glm::dot(normal, p.vertices[i]) - offset > kPlanarityTolerance * size) {
        out.push_back(
            {indexed("faces", f),
             fmt::format("vertex {} lies outside this face's plane; the polyhedron must be "
                         "convex with faces counter-clockwise seen from outside",
                         i)});
        break;
      }
    }
    for (size_t k = 0; k < face.size(); ++k) {
      const std::pair<int, int> edge{face[k], face[(k + 1) % face.size()]};
      auto [it, inserted] = edge_face.emplace(edge, f);
      if (!inserted) {
        out.push_back({indexed("faces", f),
                       fmt::format("edge {} -> {} also runs the same way in faces[{}]; adjacent "
                                   "faces must run in opposite directions along their edge",
                                   edge.first, edge.second, it->second)});
      }
    }
  }
  if (!out.empty()) return out;
  for (const auto& [edge, f] : edge_face) {
    if (!edge_face.count({edge.second, edge.first})) {
      out.push_back({indexed("faces", f),
                     fmt::format("edge {} -> {} borders no other face; the polyhedron must be "
                                 "closed",
                                 edge.first, edge.second)});
    }
  }
  return out;
}

Problems check(const Polygon& p) { return check_polygon(p.vertices); }

Problems check(const Patch& p) {
  Problems out = check_polygon(p.vertices);
  if (p.normals.size() != p.vertices.size()) {
    out.push_back({"normals", fmt::format("needs one normal per vertex: {} vertices, {} normals",
                                          p.vertices.size(), p.normals.size())});
  } else {
    check_normals(p.normals, out);
  }
  return out;
}

Problems check(const Mesh& m) {
  Problems out;
  check_finite_list(m.positions, "positions", out);
  if (m.triangles.empty()) out.push_back({"indices", "the mesh has no triangles"});
  const size_t n = m.positions.size();
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int i = m.triangles[t][k];
      if (i < 0 || static_cast<size_t>(i) >= n) {
        out.push_back({indexed("indices", 3 * t + k),
                       fmt::format("vertex index {} out of range [0, {})", i, n)});
        if (out.size() >= kMaxReported) return out;
      }
    }
  }
  if (!m.normals.empty() && m.normals.size() != n) {
    out.push_back({"normals", fmt::format("must be empty or one per position: {} positions, {} "
                                          "normals",
                                          n, m.normals.size())});
  } else {
    check_normals(m.normals, out);
  }
  return out;
}

Problems check(const Csg& c) {
  Problems out;
  if (label_name(kCsgOpLabels, c.op, "").empty()) {
    out.push_back({"op", fmt::format("unknown operation {}", static_cast<int>(c.op))});
  }
  return out;
}

Problems check(const BezierSurface& b) {
  Problems out;
  if (b.patches.empty()) out.push_back({"patches", "the surface has no patches"});
  for (size_t k = 0; k < b.patches.size(); ++k) {
    for (size_t i = 0; i < b.patches[k].points.size(); ++i) {
      check_finite(b.patches[k].points[i], fmt::format("patches[{}].points[{}]", k, i), out);
      if (out.size() >= kMaxReported) return out;
    }
  }
  return out;
}

bool is_solid(const Shape& s) {
  return std::visit(
      Overloaded{[](const Sphere&) { return true; }, [](const Cone& c) { return c.capped; },
                 [](const Polyhedron&) { return true; }, [](const Csg&) { return true; },
                 [](const auto&) { return false; }},
      s);
}

// "<file>: <path>.<field>" for parts named by a path inside the file (JSON,
// or parts without an origin), "<file>:<line>: <field>" for parts whose
// origin is already a file location (NFF objects).
std::string locate(const std::string& source, const std::string& part, const std::string& field) {
  if (part.find(':') != std::string::npos) return field.empty() ? part : part + ": " + field;
  std::string out = source.empty() ? part : source + ": " + part;
  if (!field.empty()) out += (field[0] == '[' ? "" : ".") + field;
  return out;
}

void add_all(std::vector<std::string>& out, const std::string& source, const std::string& part,
             const std::string& prefix, const Problems& problems) {
  for (const Problem& p : problems) {
    std::string field = prefix;
    if (!p.field.empty()) field += (field.empty() ? "" : ".") + p.field;
    out.push_back(locate(source, part, field) + ": " + p.what);
  }
}

}  // namespace

Problems check_shape(const Shape& shape) {
  return std::visit([](const auto& s) { return check(s); }, shape);
}

bool has_zero_area(const std::vector<Vec3>& vertices) {
  for (const Vec3& v : vertices) {
    if (!is_finite(v)) return false;
  }
  const double size = bbox_diagonal(vertices);
  return glm::length(newell_vector(vertices)) <= kAreaTolerance * size * size;
}

Problems check_polygon(const std::vector<Vec3>& vertices) {
  Problems out;
  if (vertices.size() < 3) {
    out.push_back({"vertices", fmt::format("must number at least 3, got {}", vertices.size())});
    return out;
  }
  check_finite_list(vertices, "vertices", out);
  if (!out.empty()) return out;

  // Repeated vertices anywhere, not only along an edge: a polygon that
  // touches itself has no well-defined inside for the triangulator.
  // (On the stack for the common few vertices: a polygon of a large file
  // is checked as it loads.)
  const size_t count = vertices.size();
  int few[8];
  std::vector<int> many(count > std::size(few) ? count : 0);
  int* order = many.empty() ? few : many.data();
  std::iota(order, order + count, 0);
  auto lex = [&](int a, int b) {
    const Vec3 &p = vertices[a], &q = vertices[b];
    return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
  };
  std::sort(order, order + count, lex);
  for (size_t k = 1; k < count; ++k) {
    if (vertices[order[k - 1]] == vertices[order[k]]) {
      out.push_back(
          {"vertices",
           fmt::format("{} and {} coincide at {}", std::min(order[k - 1], order[k]),
                       std::max(order[k - 1], order[k]), format_vec(vertices[order[k]]))});
      return out;
    }
  }

  const double size = bbox_diagonal(vertices);
  const Vec3 n = newell_vector(vertices);
  const double twice_area = glm::length(n);
  if (twice_area <= kAreaTolerance * size * size) {
    out.push_back({"vertices", "are all collinear; the polygon has no area"});
    return out;
  }
  const Vec3 unit = n / twice_area;
  Vec3 centroid(0.0);
  for (const Vec3& v : vertices) centroid += v;
  centroid /= static_cast<double>(vertices.size());
  double worst = 0.0;
  size_t worst_index = 0;
  for (size_t i = 0; i < vertices.size(); ++i) {
    const double d = std::abs(glm::dot(unit, vertices[i] - centroid));
    if (d > worst) {
      worst = d;
      worst_index = i;
    }
  }
  if (worst > kPlanarityTolerance * size) {
    out.push_back({"vertices", fmt::format("are not coplanar: vertex {} lies {} off the polygon's "
                                           "plane (tolerance {} of its size {})",
                                           worst_index, format_number(worst), kPlanarityTolerance,
                                           format_number(size))});
  }
  return out;
}

Problems check_camera(const Camera& c) {
  Problems out;
  check_finite(c.from, "from", out);
  check_finite(c.at, "at", out);
  check_finite(c.up, "up", out);
  if (!(c.angle > 0.0 && c.angle < 180.0)) {
    out.push_back({"angle", "must be in (0, 180) degrees, got " + format_number(c.angle)});
  }
  check_at_least(c.hither, 0.0, "hither", out);
  for (auto [v, field] : {std::pair{c.width, "width"}, {c.height, "height"}}) {
    if (v < 1 || v > kMaxResolution) {
      out.push_back({field, fmt::format("must be in [1, {}] pixels, got {}", kMaxResolution, v)});
    }
  }
  if (is_finite(c.from) && is_finite(c.at) && is_finite(c.up)) {
    const Vec3 view = c.at - c.from;
    if (glm::length(view) == 0.0) {
      out.push_back({"at", "coincides with from at " + format_vec(c.from) +
                               "; the view direction is at - from"});
    } else if (glm::length(c.up) == 0.0) {
      out.push_back({"up", "must not be zero"});
    } else if (glm::length(glm::cross(glm::normalize(view), glm::normalize(c.up))) < 1e-9) {
      out.push_back({"up", "is parallel to the view direction at - from = " + format_vec(view) +
                               "; it must point to the image's top"});
    }
  }
  return out;
}

Problems check_light(const Light& l) {
  Problems out;
  check_finite(l.position, "position", out);
  if (l.emission) check_color(*l.emission, "color", out);
  return out;
}

Problems check_material(const Material& m) {
  Problems out;
  check_color(m.color, "color", out);
  check_range(m.kd, 0.0, 1.0, "kd", out);
  check_range(m.ks, 0.0, 1.0, "ks", out);
  check_at_least(m.shine, 0.0, "shine", out);
  check_range(m.t, 0.0, 1.0, "t", out);
  check_at_least(m.ior, 1.0, "ior", out);
  check_color(m.absorption, "absorption", out);
  return out;
}

std::vector<std::string> validate_scene(const Scene& scene) {
  std::vector<std::string> out;
  const std::string& src = scene.source;
  if (!scene.has_camera) {
    out.push_back(locate(src, "camera", "") +
                  ": missing; a scene needs a camera (NFF: a v entity; JSON: \"camera\")");
  } else {
    add_all(out, src, "camera", "", check_camera(scene.camera));
  }
  {
    Problems p;
    check_color(scene.background, "", p);
    add_all(out, src, "background", "", p);
  }
  if (scene.ambient) {
    Problems p;
    check_at_least(*scene.ambient, 0.0, "", p);
    add_all(out, src, "ambient", "", p);
  }
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    add_all(out, src, indexed("lights", i), "", check_light(scene.lights[i]));
  }
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    add_all(out, src, indexed("materials", i), "", check_material(scene.materials[i]));
  }

  const int n = static_cast<int>(scene.objects.size());
  const int materials = static_cast<int>(scene.materials.size());
  std::vector<int> parent(n, -1);  // the CSG node using an object as operand
  for (int i = 0; i < n; ++i) {
    const Object& o = scene.objects[i];
    const std::string part = o.origin.empty() ? indexed("objects", i) : o.origin;
    const std::string shape(shape_name(o.shape));
    add_all(out, src, part, shape, check_shape(o.shape));
    if (o.material < 0 || o.material >= materials) {
      out.push_back(locate(src, part, "material") +
                    fmt::format(": index {} out of range; the scene has {} materials", o.material,
                                materials));
    }
    // Affine and invertible: normals go through the inverse transpose, and
    // rays are mapped into object space by the inverse.
    const Mat4& m = o.world_from_object;
    bool finite = true;
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) finite = finite && is_finite(m[c][r]);
    }
    const glm::dmat3 linear(m);
    const double scale = glm::length(linear[0]) * glm::length(linear[1]) * glm::length(linear[2]);
    if (!finite) {
      out.push_back(locate(src, part, "transform") + ": must be finite");
    } else if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0) {
      out.push_back(locate(src, part, "transform") +
                    ": must be affine (last matrix row [0, 0, 0, 1])");
    } else if (!(std::abs(glm::determinant(linear)) > 1e-12 * scale)) {
      out.push_back(locate(src, part, "transform") + ": is singular (a zero scale?)");
    }

    const auto* csg = std::get_if<Csg>(&o.shape);
    if (!csg) continue;
    for (auto [operand, field] : {std::pair{csg->left, "csg.left"}, {csg->right, "csg.right"}}) {
      const std::string where = locate(src, part, field);
      if (operand < 0 || operand >= n) {
        out.push_back(where +
                      fmt::format(": index {} out of range; the scene has {} objects", operand, n));
      } else if (operand == i) {
        out.push_back(where + ": a CSG node cannot be its own operand");
      } else if (!is_solid(scene.objects[operand].shape)) {
        out.push_back(where + fmt::format(": objects[{}] is a {}, not a solid (sphere, capped cone "
                                          "or cylinder, polyhedron, or another csg)",
                                          operand, shape_name(scene.objects[operand].shape)));
      } else if (parent[operand] >= 0) {
        out.push_back(where + fmt::format(": objects[{}] is already an operand of objects[{}]; "
                                          "an operand belongs to one CSG node",
                                          operand, parent[operand]));
      } else {
        parent[operand] = i;
      }
    }
  }
  // Each object has at most one parent, so a cycle is a closed parent chain;
  // walking up from every node with a step bound finds each one.
  std::vector<char> reported(n, 0);
  for (int i = 0; i < n; ++i) {
    int at = i;
    int steps = 0;
    while (at >= 0 && steps <= n) {
      at = parent[at];
      ++steps;
      if (at == i) break;
    }
    if (at == i && !reported[i]) {
      std::string cycle = indexed("objects", i);
      for (int k = parent[i]; k != i; k = parent[k]) {
        reported[k] = 1;
        cycle += " <- " + indexed("objects", k);
      }
      reported[i] = 1;
      const Object& o = scene.objects[i];
      out.push_back(locate(src, o.origin.empty() ? indexed("objects", i) : o.origin, "csg") +
                    ": operands form a cycle: " + cycle + " <- " + indexed("objects", i));
    }
  }
  for (std::string& p : check_animation(scene)) out.push_back(std::move(p));
  return out;
}

Status problems_status(const std::vector<std::string>& problems) {
  if (problems.empty()) return Status::Ok();
  std::string message;
  for (size_t i = 0; i < problems.size() && i < kMaxReported; ++i) {
    if (i) message += '\n';
    message += problems[i];
  }
  if (problems.size() > kMaxReported) {
    message += fmt::format("\n... and {} more problems", problems.size() - kMaxReported);
  }
  return InvalidArgument(std::move(message));
}

Result<std::string> read_text_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    return NotFound(fmt::format("{}: is a directory, not a scene file", path));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  // Read at once where the size is known (a file), through the stream
  // buffer otherwise (a pipe): a scene of a few hundred MB is not copied
  // twice nor grown by doubling.
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size > 0) {
    std::string text(static_cast<size_t>(size), '\0');
    in.seekg(0, std::ios::beg);
    in.read(text.data(), size);
    if (in.bad()) return NotFound(fmt::format("{}: cannot read: {}", path, std::strerror(errno)));
    text.resize(static_cast<size_t>(in.gcount()));
    return text;
  }
  // Empty, or a pipe: tellg failed. Clear that so the seek back is tried,
  // and clear again where a pipe refuses it too.
  in.clear();
  in.seekg(0, std::ios::beg);
  in.clear();
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return NotFound(fmt::format("{}: cannot read: {}", path, std::strerror(errno)));
  return text.str();
}

}  // namespace locus
