// The native scene format: proto/scene.proto read as JSON
// (docs/scene-format.md), and the proto conversion used on the wire.
#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <utility>

#include "common/scene/animation.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene_io.h"
#include "common/scene/validate.h"
#include "proto/scene.pb.h"

namespace locus {
namespace {

// ---- JSON syntax ----

// protobuf's JSON parser reports a syntax error with a 40-character excerpt
// and no position, and lets a repeated key silently overwrite the first. This
// strict RFC 8259 pass runs first and names the line and column, or the JSON
// path of a repeated key; it checks nothing about the schema.
class JsonSyntax {
 public:
  explicit JsonSyntax(std::string_view text) : t_(text) {}

  // Empty when the text is one well-formed JSON object.
  std::string check() {
    skip_space();
    if (pos_ >= t_.size() || t_[pos_] != '{') {
      fail("a scene file must hold one JSON object { ... }");
      return error_;
    }
    if (value(0)) {
      skip_space();
      if (pos_ < t_.size()) fail("unexpected text after the scene object");
    }
    return error_;
  }

 private:
  static constexpr int kMaxDepth = 100;  // protobuf's own recursion limit

  bool fail(const std::string& what) {
    int line = 1;
    size_t line_start = 0;
    for (size_t i = 0; i < pos_ && i < t_.size(); ++i) {
      if (t_[i] == '\n') {
        ++line;
        line_start = i + 1;
      }
    }
    error_ = fmt::format("{}:{}: {}", line, pos_ - line_start + 1, what);
    return false;
  }

  void skip_space() {
    while (pos_ < t_.size() &&
           (t_[pos_] == ' ' || t_[pos_] == '\t' || t_[pos_] == '\n' || t_[pos_] == '\r')) {
      ++pos_;
    }
  }

  std::string path() const {
    std::string out;
    for (const std::string& s : path_) out += (out.empty() || s[0] == '[' ? "" : ".") + s;
    return out.empty() ? "the top level" : out;
  }

  bool value(int depth) {
    if (depth > kMaxDepth) return fail(fmt::format("nested deeper than {} levels", kMaxDepth));
    skip_space();
    if (pos_ >= t_.size()) return fail("the file ends where a value was expected");
    switch (t_[pos_]) {
      case '{':
        return object(depth);
      case '[':
        return array(depth);
      case '"':
        return string(nullptr);
      case 't':
        return literal("true");
      case 'f':
        return literal("false");
      case 'n':
        return literal("null");
      default:
        return number();
    }
  }

  bool object(int depth) {
    ++pos_;  // {
    std::set<std::string> keys;
    skip_space();
    if (pos_ < t_.size() && t_[pos_] == '}') {
      ++pos_;
      return true;
    }
    while (true) {
      skip_space();
      if (pos_ >= t_.size() || t_[pos_] != '"') return fail("expected a \"key\" in quotes");
      const size_t key_pos = pos_;
      std::string key;
      if (!string(&key)) return false;
      // protobuf takes both spellings of a field name (base_radius and
      // baseRadius) as the same field.
      std::string normal;
      for (size_t i = 0; i < key.size(); ++i) {
        if (key[i] == '_' && i + 1 < key.size()) {
          normal += static_cast<char>(std::toupper(static_cast<unsigned char>(key[++i])));
        } else {
          normal += key[i];
        }
      }
      if (!keys.insert(normal).second) {
        pos_ = key_pos;
        return fail(fmt::format("{}: key \"{}\" appears twice", path(), key));
      }
      skip_space();
      if (pos_ >= t_.size() || t_[pos_] != ':') return fail("expected ':' after the key");
      ++pos_;
      path_.push_back(key);
      if (!value(depth + 1)) return false;
      path_.pop_back();
      skip_space();
      if (pos_ < t_.size() && t_[pos_] == ',') {
        ++pos_;
        continue;
      }
      if (pos_ < t_.size() && t_[pos_] == '}') {
        ++pos_;
        return true;
      }
      return fail("expected ',' or '}' after a value in an object");
    }
  }

  bool array(int depth) {
    ++pos_;  // [
    skip_space();
    if (pos_ < t_.size() && t_[pos_] == ']') {
      ++pos_;
      return true;
    }
    for (size_t index = 0;; ++index) {
      path_.push_back(fmt::format("[{}]", index));
      if (!value(depth + 1)) return false;
      path_.pop_back();
      skip_space();
      if (pos_ < t_.size() && t_[pos_] == ',') {
        ++pos_;
        continue;
      }
      if (pos_ < t_.size() && t_[pos_] == ']') {
        ++pos_;
        return true;
      }
      return fail("expected ',' or ']' after a value in an array");
    }
  }

  bool string(std::string* out) {
    ++pos_;  // "
    while (pos_ < t_.size()) {
      const char c = t_[pos_];
      if (c == '"') {
        ++pos_;
        return true;
      }
      if (static_cast<unsigned char>(c) < 0x20) {
        return fail("control character in a string (write \\n, \\t, ...)");
      }
      if (c == '\\') {
        const size_t start = pos_;
        if (++pos_ >= t_.size()) break;
        const char e = t_[pos_];
        if (e == 'u') {
          for (int k = 1; k <= 4; ++k) {
            if (pos_ + k >= t_.size() || !std::isxdigit(static_cast<unsigned char>(t_[pos_ + k]))) {
              return fail("\\u must be followed by 4 hex digits");
            }
          }
          pos_ += 4;
        } else if (std::string_view("\"\\/bfnrt").find(e) == std::string_view::npos) {
          return fail(fmt::format("invalid escape \\{} in a string", e));
        }
        // Keys are compared as written: only repeated keys matter here.
        if (out) *out += t_.substr(start, pos_ + 1 - start);
      } else if (out) {
        *out += c;
      }
      ++pos_;
    }
    return fail("the file ends inside a string");
  }

  bool literal(std::string_view word) {
    if (t_.substr(pos_, word.size()) != word) return fail("expected a value");
    pos_ += word.size();
    return true;
  }

  // -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?
  bool number() {
    auto digits = [&] {
      const size_t start = pos_;
      while (pos_ < t_.size() && std::isdigit(static_cast<unsigned char>(t_[pos_]))) ++pos_;
      return pos_ > start;
    };
    const size_t start = pos_;
    if (pos_ < t_.size() && t_[pos_] == '-') ++pos_;
    if (pos_ < t_.size() && t_[pos_] == '0') {
      ++pos_;
    } else if (!digits()) {
      pos_ = start;
      return fail("expected a value (a number, string, object, array, true, false or null)");
    }
    if (pos_ < t_.size() && t_[pos_] == '.') {
      ++pos_;
      if (!digits()) return fail("expected digits after the decimal point");
    }
    if (pos_ < t_.size() && (t_[pos_] == 'e' || t_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < t_.size() && (t_[pos_] == '+' || t_[pos_] == '-')) ++pos_;
      if (!digits()) return fail("expected digits in the exponent");
    }
    return true;
  }

  std::string_view t_;
  size_t pos_ = 0;
  std::vector<std::string> path_;
  std::string error_;
};

// protobuf 3.21 words errors as "(objects[0].sphere) radiuss: Cannot find
// field." or "(camera.width): invalid value 1.5 for type TYPE_INT32"; this
// turns them into "objects[0].sphere.radiuss: unknown field" and
// "camera.width: invalid value 1.5 for type TYPE_INT32".
std::string rewrite_protobuf_error(std::string_view message) {
  message = message.substr(0, message.find('\n'));
  std::string path;
  if (!message.empty() && message[0] == '(') {
    const size_t close = message.find(')');
    if (close != std::string_view::npos) {
      path = std::string(message.substr(1, close - 1));
      message.remove_prefix(close + 1);
      if (!message.empty() && message[0] == ':') message.remove_prefix(1);
      while (!message.empty() && message[0] == ' ') message.remove_prefix(1);
    }
  }
  constexpr std::string_view kUnknown = ": Cannot find field.";
  if (message.size() > kUnknown.size() && message.ends_with(kUnknown)) {
    const std::string field(message.substr(0, message.size() - kUnknown.size()));
    return fmt::format("{}{}: unknown field (docs/scene-format.md lists the fields)",
                       path.empty() ? "" : path + ".", field);
  }
  return path.empty() ? std::string(message) : path + ": " + std::string(message);
}

// ---- Proto to scene ----

using google::protobuf::RepeatedField;

class SceneFromProto {
 public:
  SceneFromProto(const std::string& name, const std::string& base_dir)
      : name_(name), base_dir_(base_dir) {}

  Result<Scene> convert(const v1::Scene& p) {
    scene_.source = name_;
    if (p.has_camera()) camera(p.camera());
    part_ = "background";
    scene_.background = vec3(p.background(), "background", Vec3(0.0)).value_or(Vec3(0.0));
    if (p.has_ambient()) scene_.ambient = p.ambient();
    for (int i = 0; i < p.lights_size(); ++i) light(p.lights(i), fmt::format("lights[{}]", i));
    for (int i = 0; i < p.materials_size(); ++i) {
      material(p.materials(i), fmt::format("materials[{}]", i));
    }
    for (int i = 0; i < p.objects_size(); ++i) {
      object(p.objects(i), fmt::format("objects[{}]", i));
    }
    if (p.has_animation()) {
      part_ = "animation";
      Result<Animation> a = animation_from_proto(p.animation(), name_.empty() ? "scene" : name_);
      if (a.ok()) {
        scene_.animation = std::move(*a);
      } else {
        // Already located ("<file>: animation.<path>: ..."), one per line.
        std::string_view lines = a.status().message();
        while (!lines.empty()) {
          const size_t end = std::min(lines.find('\n'), lines.size());
          problems_.emplace_back(lines.substr(0, end));
          lines.remove_prefix(std::min(end + 1, lines.size()));
        }
        broken_.push_back(part_);
      }
    }

    // Validation of what converted; its word on a part that already failed
    // to convert would only echo the first problem.
    std::vector<std::string> problems = std::move(problems_);
    for (std::string& v : validate_scene(scene_)) {
      const bool echo = std::any_of(broken_.begin(), broken_.end(), [&](const std::string& part) {
        const std::string prefix = where(part, "");
        return v.size() > prefix.size() && v.compare(0, prefix.size(), prefix) == 0 &&
               (v[prefix.size()] == '.' || v[prefix.size()] == ':' || v[prefix.size()] == '[');
      });
      if (!echo) problems.push_back(std::move(v));
    }
    if (!problems.empty()) return problems_status(problems);
    return std::move(scene_);
  }

 private:
  std::string where(const std::string& path, const std::string& field) const {
    std::string loc = path;
    if (!field.empty()) loc += (field[0] == '[' ? "" : ".") + field;
    return name_.empty() ? loc : name_ + ": " + loc;
  }

  // A problem at `path` (a full JSON path) within the part being converted.
  void error(const std::string& path, const std::string& what) {
    problems_.push_back(where(path, "") + ": " + what);
    if (broken_.empty() || broken_.back() != part_) broken_.push_back(part_);
  }

  std::optional<Vec3> vec3(const RepeatedField<double>& f, const std::string& path,
                           std::optional<Vec3> fallback) {
    if (f.empty() && fallback) return fallback;
    if (f.empty()) {
      error(path, "is missing (expected 3 numbers [x, y, z])");
      return std::nullopt;
    }
    if (f.size() != 3) {
      error(path, fmt::format("must hold exactly 3 numbers [x, y, z], got {}", f.size()));
      return std::nullopt;
    }
    return Vec3(f[0], f[1], f[2]);
  }

  std::vector<Vec3> points(const RepeatedField<double>& f, const std::string& path) {
    std::vector<Vec3> out;
    if (f.size() % 3 != 0) {
      error(path,
            fmt::format("must hold x, y, z triples; {} numbers is not a multiple of 3", f.size()));
      return out;
    }
    out.reserve(f.size() / 3);
    for (int i = 0; i + 2 < f.size(); i += 3) out.emplace_back(f[i], f[i + 1], f[i + 2]);
    return out;
  }

  void camera(const v1::Camera& p) {
    part_ = "camera";
    Camera& c = scene_.camera;
    c.from = vec3(p.from(), "camera.from", std::nullopt).value_or(c.from);
    c.at = vec3(p.at(), "camera.at", std::nullopt).value_or(c.at);
    c.up = vec3(p.up(), "camera.up", Vec3(0, 1, 0)).value_or(c.up);
    c.angle = p.has_angle() ? p.angle() : 45.0;
    c.hither = p.has_hither() ? p.hither() : 1e-3;
    c.width = p.width();
    c.height = p.height();
    scene_.has_camera = true;
  }

  void light(const v1::Light& p, const std::string& path) {
    part_ = path;
    Light l;
    l.position = vec3(p.position(), path + ".position", std::nullopt).value_or(Vec3(0.0));
    const double intensity = p.has_intensity() ? p.intensity() : 1.0;
    if (!p.color().empty()) {
      l.emission = intensity * vec3(p.color(), path + ".color", std::nullopt).value_or(Vec3(1.0));
    } else if (p.has_intensity()) {
      l.emission = Color(intensity);  // white of the given intensity
    }
    scene_.lights.push_back(l);
  }

  void material(const v1::Material& p, const std::string& path) {
    part_ = path;
    Material m;
    m.color = vec3(p.color(), path + ".color", Color(1.0)).value_or(Color(1.0));
    m.kd = p.has_kd() ? p.kd() : 1.0;
    m.ks = p.ks();
    m.shine = p.shine();
    m.t = p.t();
    m.ior = p.has_ior() ? p.ior() : 1.0;
    m.absorption = vec3(p.absorption(), path + ".absorption", Color(0.0)).value_or(Color(0.0));
    scene_.materials.push_back(m);
  }

  void object(const v1::Object& p, const std::string& path) {
    part_ = path;
    Object o;
    o.name = p.name();
    o.origin = path;
    o.material = p.material();
    o.world_from_object = transform(p.transform(), path + ".transform");
    if (std::optional<Shape> s = shape(p, path)) o.shape = std::move(*s);
    scene_.objects.push_back(std::move(o));
  }

  // object-to-world = translate * rotate[n-1] * ... * rotate[0] * scale, or
  // the row-major matrix (glm is column-major: m[column][row]).
  Mat4 transform(const v1::Transform& p, const std::string& path) {
    Mat4 m(1.0);
    if (!p.matrix().empty()) {
      if (!p.translate().empty() || !p.rotate().empty() || !p.scale().empty()) {
        error(path, "give either matrix or translate/rotate/scale, not both");
        return m;
      }
      if (p.matrix_size() != 16) {
        error(path + ".matrix",
              fmt::format("must hold 16 numbers (4 rows of 4), got {}", p.matrix_size()));
        return m;
      }
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) m[c][r] = p.matrix(4 * r + c);
      }
      return m;
    }
    Vec3 scale(1.0);
    if (p.scale_size() == 1) {
      scale = Vec3(p.scale(0));
    } else if (p.scale_size() == 3) {
      scale = Vec3(p.scale(0), p.scale(1), p.scale(2));
    } else if (p.scale_size() != 0) {
      error(path + ".scale",
            fmt::format("must hold 1 number (uniform) or 3 [x, y, z], got {}", p.scale_size()));
    }
    m = glm::scale(Mat4(1.0), scale);
    for (int i = 0; i < p.rotate_size(); ++i) {
      const std::string rpath = fmt::format("{}.rotate[{}]", path, i);
      const std::optional<Vec3> axis = vec3(p.rotate(i).axis(), rpath + ".axis", std::nullopt);
      if (!axis) continue;
      if (!is_finite(*axis) || glm::length(*axis) == 0.0) {
        error(rpath + ".axis", "must be a finite, non-zero vector, got " + format_vec(*axis));
        continue;
      }
      m = glm::rotate(Mat4(1.0), glm::radians(p.rotate(i).degrees()), *axis) * m;
    }
    const Vec3 t = vec3(p.translate(), path + ".translate", Vec3(0.0)).value_or(Vec3(0.0));
    return glm::translate(Mat4(1.0), t) * m;
  }

  // Problems of a derived shape (cylinder, box, prism, hull), named by the
  // fields the user wrote.
  void report(const std::string& path, const Problems& problems) {
    for (const Problem& q : problems) error(q.field.empty() ? path : path + "." + q.field, q.what);
  }

  std::optional<Shape> shape(const v1::Object& p, const std::string& path) {
    using v1::Object;
    switch (p.shape_case()) {
      case Object::kSphere: {
        const std::optional<Vec3> c = vec3(p.sphere().center(), path + ".sphere.center", Vec3(0.0));
        return Sphere{c.value_or(Vec3(0.0)), p.sphere().radius()};
      }
      case Object::kCone: {
        const auto& q = p.cone();
        const std::string at = path + ".cone";
        const std::optional<Vec3> base = vec3(q.base(), at + ".base", std::nullopt);
        const std::optional<Vec3> apex = vec3(q.apex(), at + ".apex", std::nullopt);
        if (!base || !apex) return std::nullopt;
        return Cone{*base, q.base_radius(), *apex, q.apex_radius(), q.capped()};
      }
      case Object::kCylinder: {
        const auto& q = p.cylinder();
        const std::string at = path + ".cylinder";
        const std::optional<Vec3> base = vec3(q.base(), at + ".base", std::nullopt);
        const std::optional<Vec3> apex = vec3(q.apex(), at + ".apex", std::nullopt);
        if (!base || !apex) return std::nullopt;
        const Cone c{*base, q.radius(), *apex, q.radius(), q.capped()};
        if (!(q.radius() > 0.0 && is_finite(q.radius()))) {
          error(at + ".radius", "must be positive, got " + format_number(q.radius()));
          return std::nullopt;
        }
        // With the radius fine, the cone's checks are about base and apex,
        // which the cylinder names alike.
        report(at, check_shape(c));
        return c;
      }
      case Object::kBox: {
        const std::string at = path + ".box";
        const std::optional<Vec3> lo = vec3(p.box().min(), at + ".min", std::nullopt);
        const std::optional<Vec3> hi = vec3(p.box().max(), at + ".max", std::nullopt);
        if (!lo || !hi) return std::nullopt;
        if (!is_finite(*lo) || !is_finite(*hi) ||
            !(lo->x < hi->x && lo->y < hi->y && lo->z < hi->z)) {
          error(at, fmt::format("max must exceed min in every component, got min {} and max {}",
                                format_vec(*lo), format_vec(*hi)));
          return std::nullopt;
        }
        return make_box(*lo, *hi);
      }
      case Object::kPrism: {
        const auto& q = p.prism();
        const std::string at = path + ".prism";
        const std::optional<Vec3> base = vec3(q.base(), at + ".base", std::nullopt);
        const std::optional<Vec3> apex = vec3(q.apex(), at + ".apex", std::nullopt);
        const size_t before = problems_.size();
        if (q.sides() < 3 || q.sides() > kMaxPrismSides) {
          error(at + ".sides",
                fmt::format("must be in [3, {}], got {}", kMaxPrismSides, q.sides()));
        }
        if (!(q.radius() > 0.0 && is_finite(q.radius()))) {
          error(at + ".radius", "must be positive, got " + format_number(q.radius()));
        }
        if (!is_finite(q.twist_degrees())) {
          error(at + ".twist_degrees", "must be finite, got " + format_number(q.twist_degrees()));
        }
        if (base && apex) {
          report(at, check_shape(Cone{*base, 1.0, *apex, 1.0, true}));  // base, apex as a cone's
        }
        if (!base || !apex || problems_.size() != before) return std::nullopt;
        return make_prism(q.sides(), q.radius(), *base, *apex, q.twist_degrees());
      }
      case Object::kPolyhedron: {
        const auto& q = p.polyhedron();
        const std::string at = path + ".polyhedron";
        Polyhedron out;
        out.vertices = points(q.vertices(), at + ".vertices");
        if (q.faces().empty()) return hull(out.vertices, at);
        for (const v1::Face& f : q.faces())
          out.faces.emplace_back(f.vertices().begin(), f.vertices().end());
        return out;
      }
      case Object::kPolygon:
        return Polygon{points(p.polygon().vertices(), path + ".polygon.vertices")};
      case Object::kMesh:
        return mesh(p.mesh(), path + ".mesh");
      case Object::kPatch:
        return Patch{points(p.patch().vertices(), path + ".patch.vertices"),
                     points(p.patch().normals(), path + ".patch.normals")};
      case Object::kCsg: {
        Csg c;
        switch (p.csg().op()) {
          case v1::Csg::UNION:
            c.op = CsgOp::kUnion;
            break;
          case v1::Csg::INTERSECTION:
            c.op = CsgOp::kIntersection;
            break;
          case v1::Csg::DIFFERENCE:
            c.op = CsgOp::kDifference;
            break;
          default:
            error(path + ".csg.op", fmt::format("unknown operation {} (expected UNION, "
                                                "INTERSECTION or DIFFERENCE)",
                                                static_cast<int>(p.csg().op())));
            return std::nullopt;
        }
        c.left = p.csg().left();
        c.right = p.csg().right();
        return c;
      }
      case Object::kBezier:
        return bezier(p.bezier(), path + ".bezier");
      case Object::SHAPE_NOT_SET:
        break;
    }
    error(path,
          "has no shape (expected one of sphere, cylinder, cone, box, prism, polyhedron, "
          "polygon, mesh, patch, csg, bezier)");
    return std::nullopt;
  }

  // Each patch is exactly 16 control points; their values are checked by
  // validate_scene (finite).
  std::optional<Shape> bezier(const v1::BezierSurface& p, const std::string& at) {
    BezierSurface out;
    bool ok = true;
    for (int k = 0; k < p.patches_size(); ++k) {
      const RepeatedField<double>& f = p.patches(k).points();
      if (f.size() != 48) {
        error(fmt::format("{}.patches[{}].points", at, k),
              fmt::format("must hold 48 numbers (16 control points x, y, z in rows of four), "
                          "got {}",
                          f.size()));
        ok = false;
        continue;
      }
      BezierPatch patch;
      for (int i = 0; i < 16; ++i) patch.points[i] = Vec3(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
      out.patches.push_back(patch);
    }
    if (!ok) return std::nullopt;
    return out;
  }

  std::optional<Shape> hull(const std::vector<Vec3>& vertices, const std::string& at) {
    if (vertices.size() < 4 || vertices.size() > static_cast<size_t>(kMaxHullVertices)) {
      error(at + ".vertices",
            fmt::format("the convex hull (no faces given) takes 4 to {} vertices, got {}",
                        kMaxHullVertices, vertices.size()));
      return std::nullopt;
    }
    for (size_t i = 0; i < vertices.size(); ++i) {
      if (!is_finite(vertices[i])) {
        error(fmt::format("{}.vertices[{}]", at, i),
              "must be finite, got " + format_vec(vertices[i]));
        return std::nullopt;
      }
    }
    std::optional<Polyhedron> h = make_hull(vertices);
    if (!h) {
      error(at + ".vertices", "do not span a volume (all coplanar?), so they have no convex hull");
      return std::nullopt;
    }
    return std::move(*h);
  }

  std::optional<Shape> mesh(const v1::Mesh& p, const std::string& at) {
    if (p.obj().empty()) {
      Mesh m;
      m.positions = points(p.positions(), at + ".positions");
      m.normals = points(p.normals(), at + ".normals");
      if (p.indices_size() % 3 != 0) {
        error(at + ".indices",
              fmt::format("must hold 3 per triangle; {} is not a multiple of 3", p.indices_size()));
        return std::nullopt;
      }
      for (int i = 0; i + 2 < p.indices_size(); i += 3) {
        m.triangles.push_back({p.indices(i), p.indices(i + 1), p.indices(i + 2)});
      }
      return m;
    }
    if (!p.positions().empty() || !p.normals().empty() || !p.indices().empty()) {
      error(at, "give either obj or inline positions/normals/indices, not both");
      return std::nullopt;
    }
    std::filesystem::path file(p.obj());
    if (file.is_relative() && !base_dir_.empty()) file = std::filesystem::path(base_dir_) / file;
    return load_obj(file.string(), at + ".obj");
  }

  // A triangulated OBJ file. Normals are kept only when every corner has
  // one; a vertex is then a distinct (position, normal) pair.
  std::optional<Shape> load_obj(const std::string& file, const std::string& at) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) {
      error(at, fmt::format("cannot read '{}': no such file (paths are relative to the scene "
                            "file)",
                            file));
      return std::nullopt;
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
      error(at, fmt::format("cannot load '{}': {}", file, why));
      return std::nullopt;
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
            error(at, fmt::format("'{}': a face refers to a vertex or normal that does not exist",
                                  file));
            return std::nullopt;
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

  std::string name_;
  std::string base_dir_;
  Scene scene_;
  std::string part_;                 // the part being converted: "objects[3]"
  std::vector<std::string> broken_;  // parts that failed to convert
  std::vector<std::string> problems_;
};

// ---- Scene to proto ----

void put(RepeatedField<double>* f, const Vec3& v) {
  f->Clear();
  f->Add(v.x);
  f->Add(v.y);
  f->Add(v.z);
}

void put(RepeatedField<double>* f, const std::vector<Vec3>& points) {
  f->Clear();
  f->Reserve(static_cast<int>(3 * points.size()));
  for (const Vec3& p : points) {
    f->Add(p.x);
    f->Add(p.y);
    f->Add(p.z);
  }
}

struct ShapeToProto {
  v1::Object* o;
  void operator()(const Sphere& s) const {
    put(o->mutable_sphere()->mutable_center(), s.center);
    o->mutable_sphere()->set_radius(s.radius);
  }
  void operator()(const Cone& c) const {
    v1::Cone* q = o->mutable_cone();
    put(q->mutable_base(), c.base);
    q->set_base_radius(c.base_radius);
    put(q->mutable_apex(), c.apex);
    q->set_apex_radius(c.apex_radius);
    q->set_capped(c.capped);
  }
  void operator()(const Polyhedron& p) const {
    v1::Polyhedron* q = o->mutable_polyhedron();
    put(q->mutable_vertices(), p.vertices);
    for (const std::vector<int>& f : p.faces) {
      q->add_faces()->mutable_vertices()->Add(f.begin(), f.end());
    }
  }
  void operator()(const Polygon& p) const {
    put(o->mutable_polygon()->mutable_vertices(), p.vertices);
  }
  void operator()(const Mesh& m) const {
    v1::Mesh* q = o->mutable_mesh();
    put(q->mutable_positions(), m.positions);
    put(q->mutable_normals(), m.normals);
    q->mutable_indices()->Reserve(static_cast<int>(3 * m.triangles.size()));
    for (const auto& t : m.triangles) q->mutable_indices()->Add(t.begin(), t.end());
  }
  void operator()(const Patch& p) const {
    put(o->mutable_patch()->mutable_vertices(), p.vertices);
    put(o->mutable_patch()->mutable_normals(), p.normals);
  }
  void operator()(const BezierSurface& b) const {
    v1::BezierSurface* q = o->mutable_bezier();
    for (const BezierPatch& patch : b.patches) {
      put(q->add_patches()->mutable_points(),
          std::vector<Vec3>(patch.points.begin(), patch.points.end()));
    }
  }
  void operator()(const Csg& c) const {
    v1::Csg* q = o->mutable_csg();
    q->set_op(c.op == CsgOp::kUnion          ? v1::Csg::UNION
              : c.op == CsgOp::kIntersection ? v1::Csg::INTERSECTION
                                             : v1::Csg::DIFFERENCE);
    q->set_left(c.left);
    q->set_right(c.right);
  }
};

}  // namespace

v1::Scene scene_to_proto(const Scene& scene) {
  v1::Scene p;
  if (scene.has_camera) {
    const Camera& c = scene.camera;
    v1::Camera* q = p.mutable_camera();
    put(q->mutable_from(), c.from);
    put(q->mutable_at(), c.at);
    put(q->mutable_up(), c.up);
    q->set_angle(c.angle);
    q->set_hither(c.hither);
    q->set_width(c.width);
    q->set_height(c.height);
  }
  put(p.mutable_background(), scene.background);
  if (scene.ambient) p.set_ambient(*scene.ambient);
  for (const Light& l : scene.lights) {
    v1::Light* q = p.add_lights();
    put(q->mutable_position(), l.position);
    if (l.emission) put(q->mutable_color(), *l.emission);
  }
  for (const Material& m : scene.materials) {
    v1::Material* q = p.add_materials();
    put(q->mutable_color(), m.color);
    q->set_kd(m.kd);
    q->set_ks(m.ks);
    q->set_shine(m.shine);
    q->set_t(m.t);
    q->set_ior(m.ior);
    put(q->mutable_absorption(), m.absorption);
  }
  if (!scene.animation.empty()) animation_to_proto(scene.animation, p.mutable_animation());
  for (const Object& o : scene.objects) {
    v1::Object* q = p.add_objects();
    q->set_name(o.name);
    std::visit(ShapeToProto{q}, o.shape);
    q->set_material(o.material);
    if (o.world_from_object != Mat4(1.0)) {
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) q->mutable_transform()->add_matrix(o.world_from_object[c][r]);
      }
    }
  }
  return p;
}

Result<Scene> scene_from_proto(const v1::Scene& proto, const std::string& name,
                               const std::string& base_dir) {
  return SceneFromProto(name, base_dir).convert(proto);
}

Result<Scene> parse_scene_json(std::string_view text, const std::string& name,
                               const std::string& base_dir) {
  if (std::string error = JsonSyntax(text).check(); !error.empty()) {
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
