// The scene model: plain structs, objects refer to each other by index.
// Conventions (camera, lights, materials) are those of ../shared/SHADING.md,
// restated in docs/conventions.md.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "common/base/labels.h"
#include "common/base/math.h"
#include "common/scene/animation.h"

namespace locus {

// SHADING.md "Camera and pixels". angle is the full vertical field of view in
// degrees, edge to edge of the image.
struct Camera {
  Vec3 from{0, 0, 1};
  Vec3 at{0, 0, 0};
  Vec3 up{0, 1, 0};
  double angle = 45.0;
  double hither = 1e-3;
  int width = 256;
  int height = 256;
};

// A point light. When `emission` is empty the light takes the SPD default
// intensity sqrt(L) / (2L) in every channel (L = number of lights); a given
// colour (times intensity) replaces it.
struct Light {
  Vec3 position{0, 0, 0};
  std::optional<Color> emission;
};

// NFF "f r g b Kd Ks Shine T ior", plus a per-channel absorption coefficient
// q for Lambert-Beer attenuation inside the body (paper eq. (3)).
struct Material {
  Color color{1, 1, 1};
  double kd = 1.0;
  double ks = 0.0;
  double shine = 0.0;
  double t = 0.0;  // transmission coefficient T
  double ior = 1.0;
  Color absorption{0, 0, 0};
};

// ---- Shapes, in object space ----

struct Sphere {
  Vec3 center{0, 0, 0};
  double radius = 1.0;
};

// Cylinder, cone and truncated cone (frustum): the surface between two
// circles centred on the axis points `base` and `apex`. Equal radii make a
// cylinder, apex_radius == 0 a cone. Without caps the surface is open (NFF).
struct Cone {
  Vec3 base{0, 0, 0};
  double base_radius = 1.0;
  Vec3 apex{0, 0, 1};
  double apex_radius = 1.0;
  bool capped = false;
};

// A convex polyhedron given by its faces. Each face lists vertex indices
// counter-clockwise seen from outside. Boxes, prisms and hulls of point sets
// are built into this form by the helpers in polyhedron.h.
struct Polyhedron {
  std::vector<Vec3> vertices;
  std::vector<std::vector<int>> faces;
};

// A planar polygon, convex or concave. Front side: vertices run
// counter-clockwise (SHADING.md "Entering or leaving").
struct Polygon {
  std::vector<Vec3> vertices;
};

// A triangle mesh; `normals` is empty or holds one normal per vertex.
struct Mesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  std::vector<std::array<int, 3>> triangles;
};

// NFF "pp": a planar polygon with a normal per vertex, interpolated
// barycentrically over a fan triangulation (SHADING.md "Geometry").
struct Patch {
  std::vector<Vec3> vertices;
  std::vector<Vec3> normals;
};

// A free-form surface (METHOD.md §3): bicubic Bezier patches sharing one
// material and transform. A patch's 16 control points are listed in rows of
// four: points[4 * i + j] = P_ij, and the patch is
// S(u, v) = sum_ij B_i(v) B_j(u) P_ij with Bernstein polynomials B of degree
// 3, so u runs along a row and v across the rows. Neighbouring patches join
// where their boundary rows or columns hold the same four points (as when
// both are written from one vertex table, like the Utah teapot). The
// renderer tessellates the surface per frame to a screen-space tolerance
// (common/prepare/tessellate.h, docs/tessellation.md).
struct BezierPatch {
  std::array<Vec3, 16> points{};
};
struct BezierSurface {
  std::vector<BezierPatch> patches;
};

enum class CsgOp { kUnion, kIntersection, kDifference };
// The names of the operations as a scene file writes them (scene.proto's
// Csg.Op) and messages list them.
inline constexpr Labels<CsgOp, 3> kCsgOpLabels = {{{CsgOp::kUnion, "UNION"},
                                                   {CsgOp::kIntersection, "INTERSECTION"},
                                                   {CsgOp::kDifference, "DIFFERENCE"}}};

// A set operation of two solids, given as indices into Scene::objects. The
// operands are not rendered on their own.
struct Csg {
  CsgOp op = CsgOp::kUnion;
  int left = -1;
  int right = -1;
};

using Shape = std::variant<Sphere, Cone, Polyhedron, Polygon, Mesh, Patch, Csg, BezierSurface>;

// The alternatives of Shape, in its order, and their names in messages and
// JSON paths ("objects[3].sphere.radius"): the JSON format's shape fields of
// the same names (scene_proto.cpp) give exactly these shapes.
enum class ShapeKind { kSphere, kCone, kPolyhedron, kPolygon, kMesh, kPatch, kCsg, kBezier };
inline constexpr Labels<ShapeKind, 8> kShapeLabels = {{{ShapeKind::kSphere, "sphere"},
                                                       {ShapeKind::kCone, "cone"},
                                                       {ShapeKind::kPolyhedron, "polyhedron"},
                                                       {ShapeKind::kPolygon, "polygon"},
                                                       {ShapeKind::kMesh, "mesh"},
                                                       {ShapeKind::kPatch, "patch"},
                                                       {ShapeKind::kCsg, "csg"},
                                                       {ShapeKind::kBezier, "bezier"}}};
inline ShapeKind shape_kind(const Shape& shape) { return static_cast<ShapeKind>(shape.index()); }
inline std::string_view shape_name(const Shape& shape) {
  return label_name(kShapeLabels, shape_kind(shape));
}

namespace detail {
template <ShapeKind K, class T>
inline constexpr bool kShapeKindIs =
    std::is_same_v<std::variant_alternative_t<static_cast<size_t>(K), Shape>, T>;
}  // namespace detail
static_assert(std::variant_size_v<Shape> == kShapeLabels.size());
static_assert(detail::kShapeKindIs<ShapeKind::kSphere, Sphere> &&
                  detail::kShapeKindIs<ShapeKind::kCone, Cone> &&
                  detail::kShapeKindIs<ShapeKind::kPolyhedron, Polyhedron> &&
                  detail::kShapeKindIs<ShapeKind::kPolygon, Polygon> &&
                  detail::kShapeKindIs<ShapeKind::kMesh, Mesh> &&
                  detail::kShapeKindIs<ShapeKind::kPatch, Patch> &&
                  detail::kShapeKindIs<ShapeKind::kCsg, Csg> &&
                  detail::kShapeKindIs<ShapeKind::kBezier, BezierSurface>,
              "ShapeKind follows the order of Shape's alternatives");

struct Object {
  Shape shape;
  int material = 0;          // index into Scene::materials
  Mat4 world_from_object{1.0};
  std::string name;          // optional, for messages
  std::string origin;        // where it was defined: "file.nff:12" or "objects[3]"
};

struct Scene {
  Camera camera;
  bool has_camera = false;
  Color background{0, 0, 0};
  std::optional<double> ambient;  // default sqrt(L)/(2L), 0 without lights
  std::vector<Light> lights;
  std::vector<Material> materials;
  std::vector<Object> objects;
  Animation animation;  // keyframes (animation.h); empty for a still scene
  std::string source;  // file the scene was read from, for messages
};

// Resolved light intensities: SHADING.md "Lights".
Color light_emission(const Scene& scene, int light);
double ambient_intensity(const Scene& scene);

// True for objects that are operands of some CSG node (rendered through it).
std::vector<bool> csg_operand_mask(const Scene& scene);

}  // namespace locus
