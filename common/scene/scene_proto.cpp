// The scene <-> proto conversion (scene_io.h): scene_from_proto checks and
// converts a v1::Scene (parsed from a JSON file, or received on the wire)
// into the scene model, naming each problem by its JSON path, and
// scene_to_proto writes the wire form. The JSON text itself is checked in
// json_syntax.cpp, OBJ files are read in obj.cpp.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "common/base/labels.h"
#include "common/scene/animation.h"
#include "common/scene/obj.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene_io.h"
#include "common/scene/validate.h"
#include "proto/scene.pb.h"

namespace locus {
namespace {

using google::protobuf::RepeatedField;

constexpr std::string_view named(ShapeKind kind) { return label_name(kShapeLabels, kind); }

// The fields that give a JSON object its shape (scene.proto's oneof
// `shape`), in the proto's order: they name the object's JSON path
// ("objects[3].cone.base") and the choices when none is given. The scene's
// own shapes keep their names (kShapeLabels); cylinder, box and prism are
// forms the file may write, which become a cone or a polyhedron.
constexpr Labels<v1::Object::ShapeCase, 11> kShapeFields = {{
    {v1::Object::kSphere, named(ShapeKind::kSphere)},
    {v1::Object::kCylinder, "cylinder"},
    {v1::Object::kCone, named(ShapeKind::kCone)},
    {v1::Object::kBox, "box"},
    {v1::Object::kPrism, "prism"},
    {v1::Object::kPolyhedron, named(ShapeKind::kPolyhedron)},
    {v1::Object::kPolygon, named(ShapeKind::kPolygon)},
    {v1::Object::kMesh, named(ShapeKind::kMesh)},
    {v1::Object::kPatch, named(ShapeKind::kPatch)},
    {v1::Object::kCsg, named(ShapeKind::kCsg)},
    {v1::Object::kBezier, named(ShapeKind::kBezier)},
}};

// "sphere, cylinder, ..., bezier".
std::string shape_field_list() {
  std::string out;
  for (const auto& field : kShapeFields) {
    if (!out.empty()) out += ", ";
    out += field.name;
  }
  return out;
}

// ---- Proto to scene ----

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
    // Reserved: growing moved every Object (280 bytes, a variant) at each
    // doubling and touched fresh pages for all of them, the larger part
    // of converting SPD tetra level 9 (262,144 polygons).
    scene_.objects.reserve(static_cast<size_t>(p.objects_size()));
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

  // One function per shape field; `at` is the field's JSON path
  // ("objects[3].cone").
  std::optional<Shape> shape(const v1::Object& p, const std::string& path) {
    using v1::Object;
    if (p.shape_case() == Object::SHAPE_NOT_SET) {
      error(path, "has no shape (expected one of " + shape_field_list() + ")");
      return std::nullopt;
    }
    const std::string at = path + "." + std::string(label_name(kShapeFields, p.shape_case()));
    switch (p.shape_case()) {
      case Object::kSphere:
        return sphere(p.sphere(), at);
      case Object::kCone:
        return cone(p.cone(), at);
      case Object::kCylinder:
        return cylinder(p.cylinder(), at);
      case Object::kBox:
        return box(p.box(), at);
      case Object::kPrism:
        return prism(p.prism(), at);
      case Object::kPolyhedron:
        return polyhedron(p.polyhedron(), at);
      case Object::kPolygon:
        return Polygon{points(p.polygon().vertices(), at + ".vertices")};
      case Object::kMesh:
        return mesh(p.mesh(), at);
      case Object::kPatch:
        return Patch{points(p.patch().vertices(), at + ".vertices"),
                     points(p.patch().normals(), at + ".normals")};
      case Object::kCsg:
        return csg(p.csg(), at);
      case Object::kBezier:
        return bezier(p.bezier(), at);
      case Object::SHAPE_NOT_SET:
        break;
    }
    return std::nullopt;
  }

  std::optional<Shape> sphere(const v1::Sphere& q, const std::string& at) {
    const std::optional<Vec3> c = vec3(q.center(), at + ".center", Vec3(0.0));
    return Sphere{c.value_or(Vec3(0.0)), q.radius()};
  }

  std::optional<Shape> cone(const v1::Cone& q, const std::string& at) {
    const std::optional<Vec3> base = vec3(q.base(), at + ".base", std::nullopt);
    const std::optional<Vec3> apex = vec3(q.apex(), at + ".apex", std::nullopt);
    if (!base || !apex) return std::nullopt;
    return Cone{*base, q.base_radius(), *apex, q.apex_radius(), q.capped()};
  }

  // A cone of equal radii.
  std::optional<Shape> cylinder(const v1::Cylinder& q, const std::string& at) {
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

  // An axis-aligned box, as a polyhedron.
  std::optional<Shape> box(const v1::Box& q, const std::string& at) {
    const std::optional<Vec3> lo = vec3(q.min(), at + ".min", std::nullopt);
    const std::optional<Vec3> hi = vec3(q.max(), at + ".max", std::nullopt);
    if (!lo || !hi) return std::nullopt;
    if (!is_finite(*lo) || !is_finite(*hi) || !(lo->x < hi->x && lo->y < hi->y && lo->z < hi->z)) {
      error(at, fmt::format("max must exceed min in every component, got min {} and max {}",
                            format_vec(*lo), format_vec(*hi)));
      return std::nullopt;
    }
    return make_box(*lo, *hi);
  }

  // A right prism over a regular n-gon, as a polyhedron.
  std::optional<Shape> prism(const v1::Prism& q, const std::string& at) {
    const std::optional<Vec3> base = vec3(q.base(), at + ".base", std::nullopt);
    const std::optional<Vec3> apex = vec3(q.apex(), at + ".apex", std::nullopt);
    const size_t before = problems_.size();
    if (q.sides() < 3 || q.sides() > kMaxPrismSides) {
      error(at + ".sides", fmt::format("must be in [3, {}], got {}", kMaxPrismSides, q.sides()));
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

  // Given faces, or (none given) the convex hull of the vertices.
  std::optional<Shape> polyhedron(const v1::Polyhedron& q, const std::string& at) {
    Polyhedron out;
    out.vertices = points(q.vertices(), at + ".vertices");
    if (q.faces().empty()) return hull(out.vertices, at);
    for (const v1::Face& f : q.faces()) {
      out.faces.emplace_back(f.vertices().begin(), f.vertices().end());
    }
    return out;
  }

  std::optional<Shape> csg(const v1::Csg& q, const std::string& at) {
    Csg c;
    switch (q.op()) {
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
        error(at + ".op", fmt::format("unknown operation {} (expected {})",
                                      static_cast<int>(q.op()), label_choices(kCsgOpLabels)));
        return std::nullopt;
    }
    c.left = q.left();
    c.right = q.right();
    return c;
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
    Result<Mesh> m = load_obj(file.string());
    if (!m.ok()) {
      error(at + ".obj", m.status().message());
      return std::nullopt;
    }
    return std::move(*m);
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
  p.mutable_objects()->Reserve(static_cast<int>(scene.objects.size()));
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

}  // namespace locus
