// Bounding convex polyhedra of curved bodies (paper §3.1, Fig. 3;
// METHOD.md §3). The scanline pass scan-converts these polyhedra in place of
// the curved surfaces; inside their spans the true surface is found by ray
// intersection (paper §3.2). They follow the body, not the world axes, so a
// tilted cylinder wastes far fewer rays than with a world-axis box
// (docs/bounding.md has the figures).
//
// Every polyhedron returned here is convex with planar faces listed
// counter-clockwise seen from outside (scene.h Polyhedron), vertices in the
// space the given transform maps to (world space for the scene-level call).
#pragma once

#include <optional>
#include <vector>

#include "common/base/math.h"
#include "common/scene/scene.h"

namespace locus {

// A sphere, or under a non-uniform transform an ellipsoid: the image of the
// circumscribed icosahedron (20 faces, each tangent to the sphere; its volume
// is 1.21 times the sphere's). An affine image of a circumscribing
// polyhedron circumscribes the image of the sphere, so ellipsoids need
// nothing more. docs/bounding.md weighs the face count against tightness.
Polyhedron bounding_polyhedron(const Sphere& s, const Mat4& world_from_object);

// A cylinder or frustum: the hexahedron whose end faces are the squares
// circumscribing the end circles, aligned with the axis (paper Fig. 3); a
// cone (one radius 0, at either end): the square pyramid over the other end's
// square. Open and capped bodies get the same polyhedron. Expects a valid
// cone (validate.h: radii >= 0 and not both 0, base != apex).
Polyhedron bounding_polyhedron(const Cone& c, const Mat4& world_from_object);

// The polyhedra, in world space, that bound scene object `object`: one for a
// sphere or cone; for a CSG node, one per leaf, with the node transforms
// composed down the tree as primitives.cpp does (world_from_leaf =
// world_from_root * ... * leaf.world_from_object), polyhedron leaves
// transformed as they are; for a polyhedron object, itself; none for
// polygons, meshes and patches (the scanline pass takes their faces as
// they are). `object` must index scene.objects.
std::vector<Polyhedron> bounding_polyhedra(const Scene& scene, int object);

// The polyhedron bounded by the planes tangent to the unit sphere at the
// given unit normals (n . x <= 1), or nullopt if they do not enclose a
// bounded volume (some open hemisphere holds no normal). Every normal gives
// one face. The sphere's polyhedron above is this one for the 20 vertex
// directions of a dodecahedron; exposed so tests can weigh other choices.
std::optional<Polyhedron> circumscribed_polyhedron(const std::vector<Vec3>& normals);

// `p` mapped by an affine transform, faces still counter-clockwise seen from
// outside (a transform with negative determinant mirrors, so the windings
// are reversed).
Polyhedron transform_polyhedron(Polyhedron p, const Mat4& world_from_object);

}  // namespace locus
