// Bounding convex polyhedra of curved bodies (bounding.h; paper §3.1,
// Fig. 3). Built in object space, where the body is a round sphere or a
// circular cone, then mapped by the object's affine transform: the image of
// a circumscribing polyhedron circumscribes the image of the body.
#include "common/prepare/bounding.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "common/scene/polyhedron.h"

namespace locus {
namespace {

// Outward normal of a face of a make_hull result: every vertex is a corner
// of a convex polygon, so the first three span it.
Vec3 hull_face_normal(const Polyhedron& p, const std::vector<int>& face) {
  const Vec3& a = p.vertices[face[0]];
  return glm::normalize(glm::cross(p.vertices[face[1]] - a, p.vertices[face[2]] - a));
}

// The face normals of the sphere's polyhedron: the 20 vertex directions of a
// regular dodecahedron, whose tangent planes bound the circumscribed
// icosahedron (docs/bounding.md: 20 faces and 12 vertices for a volume 1.21
// times the sphere's).
std::vector<Vec3> icosahedron_normals() {
  const double phi = std::numbers::phi, iphi = 1.0 / phi;
  std::vector<Vec3> n;
  for (double a : {-1.0, 1.0}) {
    for (double b : {-1.0, 1.0}) {
      for (double c : {-1.0, 1.0}) n.emplace_back(a, b, c);
      n.emplace_back(0.0, a * iphi, b * phi);
      n.emplace_back(a * iphi, b * phi, 0.0);
      n.emplace_back(a * phi, 0.0, b * iphi);
    }
  }
  for (Vec3& v : n) v = glm::normalize(v);
  return n;
}

// The circumscribed icosahedron of the unit sphere at the origin, built once.
const Polyhedron& unit_sphere_polyhedron() {
  static const Polyhedron* const kUnit =
      new Polyhedron(*circumscribed_polyhedron(icosahedron_normals()));
  return *kUnit;
}

// Object-space polyhedron of a cone: the squares of half-side r circumscribe
// the end circles (paper Fig. 3), their sides parallel to u and v; a zero
// radius collapses its square to the axis point, making a square pyramid.
Polyhedron cone_polyhedron(const Cone& c) {
  const Vec3 axis = glm::normalize(c.apex - c.base);
  // (u, v, axis) right-handed, so corners in increasing k run
  // counter-clockwise seen from the apex side.
  const Vec3 u = any_perpendicular(axis);
  const Vec3 v = glm::cross(axis, u);
  const double su[4] = {1, -1, -1, 1}, sv[4] = {1, 1, -1, -1};
  Polyhedron p;
  // Index of corner k of the base (end 0) or apex (end 1) square.
  int corner[2][4];
  for (int end = 0; end < 2; ++end) {
    const Vec3& centre = end == 0 ? c.base : c.apex;
    const double r = end == 0 ? c.base_radius : c.apex_radius;
    for (int k = 0; k < 4; ++k) {
      if (r > 0.0 || k == 0) p.vertices.push_back(centre + r * (su[k] * u + sv[k] * v));
      corner[end][k] = static_cast<int>(p.vertices.size()) - 1;
    }
  }
  // Each end face is a square, or nothing where the body comes to a point.
  if (c.base_radius > 0.0) {
    p.faces.push_back({corner[0][3], corner[0][2], corner[0][1], corner[0][0]});
  }
  if (c.apex_radius > 0.0) {
    p.faces.push_back({corner[1][0], corner[1][1], corner[1][2], corner[1][3]});
  }
  for (int k = 0; k < 4; ++k) {
    const int j = (k + 1) % 4;
    // A side face of the hexahedron is the quad between the two squares'
    // parallel edges; it touches the side surface along a generator. At a
    // pointed end its two corners coincide and it is a triangle.
    std::vector<int> face = {corner[0][k], corner[0][j], corner[1][j], corner[1][k]};
    face.erase(std::unique(face.begin(), face.end()), face.end());
    if (face.front() == face.back()) face.pop_back();
    p.faces.push_back(std::move(face));
  }
  return p;
}

// Appends the world-space polyhedra of the CSG subtree at `obj`, composing
// transforms the way primitives.cpp's Builder::add_csg_node does.
void add_csg_leaves(const Scene& scene, int obj, const Mat4& parent_xf,
                    std::vector<Polyhedron>& out) {
  const Object& o = scene.objects.at(obj);
  const Mat4 xf = parent_xf * o.world_from_object;
  if (const auto* c = std::get_if<Csg>(&o.shape)) {
    add_csg_leaves(scene, c->left, xf, out);
    add_csg_leaves(scene, c->right, xf, out);
  } else if (const auto* s = std::get_if<Sphere>(&o.shape)) {
    out.push_back(bounding_polyhedron(*s, xf));
  } else if (const auto* cn = std::get_if<Cone>(&o.shape)) {
    out.push_back(bounding_polyhedron(*cn, xf));
  } else if (const auto* ph = std::get_if<Polyhedron>(&o.shape)) {
    out.push_back(transform_polyhedron(*ph, xf));
  }
  // Other shapes are rejected as CSG operands by validate_scene().
}

}  // namespace

std::optional<Polyhedron> circumscribed_polyhedron(const std::vector<Vec3>& normals) {
  // Polar duality: a vertex x of {x : n_i . x <= 1} is where the planes of
  // the normals on one face of their convex hull meet; for that face's plane
  // m . y = d, x = m / d. The tangent planes bound a finite volume exactly
  // when the origin is strictly inside the hull (d > 0 for every face).
  const std::optional<Polyhedron> hull = make_hull(normals);
  if (!hull) return std::nullopt;
  std::vector<Vec3> vertices;
  for (const auto& face : hull->faces) {
    const Vec3 m = hull_face_normal(*hull, face);
    const double d = glm::dot(m, hull->vertices[face[0]]);
    if (!(d > 1e-9)) return std::nullopt;
    vertices.push_back(m / d);
  }
  // The hull of the vertices is the polyhedron itself, faces merged and
  // wound counter-clockwise from outside by make_hull.
  return make_hull(vertices);
}

Polyhedron transform_polyhedron(Polyhedron p, const Mat4& world_from_object) {
  // Taken by value: a caller's temporary is moved in, not copied (a
  // sphere's 20 faces are not allocated twice per sphere).
  Polyhedron out = std::move(p);
  if (world_from_object == Mat4(1.0)) return out;
  for (Vec3& v : out.vertices) v = transform_point(world_from_object, v);
  if (glm::determinant(glm::dmat3(world_from_object)) < 0.0) {
    for (auto& face : out.faces) std::reverse(face.begin(), face.end());
  }
  return out;
}

Polyhedron bounding_polyhedron(const Sphere& s, const Mat4& world_from_object) {
  const Polyhedron& unit = unit_sphere_polyhedron();
  Polyhedron p = unit;
  for (Vec3& v : p.vertices) v = s.center + s.radius * v;
  return transform_polyhedron(std::move(p), world_from_object);
}

Polyhedron bounding_polyhedron(const Cone& c, const Mat4& world_from_object) {
  return transform_polyhedron(cone_polyhedron(c), world_from_object);
}

std::vector<Polyhedron> bounding_polyhedra(const Scene& scene, int object) {
  const Object& o = scene.objects.at(object);
  std::vector<Polyhedron> out;
  if (const auto* s = std::get_if<Sphere>(&o.shape)) {
    out.push_back(bounding_polyhedron(*s, o.world_from_object));
  } else if (const auto* c = std::get_if<Cone>(&o.shape)) {
    out.push_back(bounding_polyhedron(*c, o.world_from_object));
  } else if (const auto* ph = std::get_if<Polyhedron>(&o.shape)) {
    out.push_back(transform_polyhedron(*ph, o.world_from_object));
  } else if (std::holds_alternative<Csg>(o.shape)) {
    add_csg_leaves(scene, object, Mat4(1.0), out);
  }
  return out;
}

}  // namespace locus
