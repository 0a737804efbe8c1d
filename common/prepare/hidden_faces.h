// Faces that cannot matter from a viewpoint: the back faces of closed
// convex solids. A closed convex solid hides the faces it turns away from a
// point outside it behind the faces it turns towards that point: a ray
// from there enters the solid through a front face before it can leave
// through a back one, and a segment to there leaves the solid through a
// front face. So
// - the scanline pass (paper §3.1, the visible face among all faces
//   crossing a sample line) leaves out the faces turned away from the eye
//   of solids wholly in front of the near plane and of hither: they are
//   never the nearest, and only cost their crossings and depth tests;
// - eye rays (from the eye point) skip them too;
// - shadow rays to a light (eq. (2): an opaque occluder stops the light)
//   skip the faces an opaque solid turns away from the light, where the
//   light lies outside the solid.
// SPD tetra is such solids, four polygons each: at level 9 half of its
// 262,144 faces face away from the eye, and half away from the light
// (docs/renderer.md, "Back faces of closed solids").
#pragma once

#include <cstdint>
#include <vector>

#include "common/geometry/geometry.h"
#include "common/scene/scene.h"

namespace locus {

struct CameraFrame;

// The closed convex solids made of the scene's polygons: polygons whose
// vertices, matched exactly, join every edge to exactly one other
// polygon's, walked the other way (one orientation), enclosing a volume,
// with no vertex outside any face's plane. Any doubt (an open or bent
// surface, an edge of three faces, a reversed face, a concave or flat
// solid, more than kMaxSolidFaces faces) leaves the polygons out.
struct ClosedSolids {
  // Solid s: its polygons (prim indices) faces[first[s], first[s + 1]),
  // and sign[s] = +1 where their own normals (counter-clockwise) point out
  // of it, -1 where they point in.
  std::vector<int> first{0};
  std::vector<int> faces;
  std::vector<double> sign;
  // How far outside a face's plane a vertex of solid s may lie (1e-9 of its
  // box's diagonal and 1e-12 of its coordinates): rounding, not shape.
  std::vector<double> tolerance;
  int count() const { return static_cast<int>(sign.size()); }
};

// Solids of more faces are not examined (the convexity check is faces x
// vertices).
inline constexpr int kMaxSolidFaces = 64;

ClosedSolids closed_convex_solids(const PrimitiveSet& set);

// Per primitive, which rays may skip it (bits; 0 for primitives of no solid):
// kCullEye: it faces away from the eye, its solid lies wholly deeper than
// z_near and the camera's hither (so the eye is outside it and nothing of
// it is clipped); cull_light(j), for lights j < kCullLights: it faces away
// from light j, its solid is opaque (every face stops_light) and the light
// lies outside it.
inline constexpr uint8_t kCullEye = 1;
inline constexpr int kCullLights = 7;
inline constexpr uint8_t cull_light(int j) { return static_cast<uint8_t>(2u << j); }
std::vector<uint8_t> ray_culls(const PrimitiveSet& set, const ClosedSolids& solids,
                               const CameraFrame& cam, double z_near,
                               const std::vector<Light>& lights,
                               const std::vector<uint8_t>& stops_light);

// A shadow ray from a face of an opaque closed convex solid to a light in
// front of the face meets none of the solid's faces, and skips them (at
// SPD tetra level 9 about half of a shadow ray's tests were its own
// solid's faces). Why: its origin is offset by eps (PreparedScene::eps) to
// the light's side of the face (Tracer::shadow_origin), which is the front,
// outside the solid, as the light lies at least `margin` = eps + 1e-12 |L|
// in front of the face's plane (far above the rounding of the side test
// and of the shaded point, about 1e-15 of the scene's size); the segment
// from there to the light lies at least about eps in front of the plane,
// where no part of the solid is (its vertices lie behind every face's plane
// to 1e-9 of its size, closed_convex_solids), and every other face's plane
// meets it at least eps from that face, far beyond the rounding of the
// exact tests. So the skipped tests would all have missed. Per primitive
// (empty: none), for solids whose faces are consecutive primitives:
inline constexpr int kOwnSolidLights = 8;
struct OwnSolid {
  int first = 0;       // the solid's faces: prims [first, first + count)
  int16_t count = 0;   // 0: in no such solid
  uint8_t lights = 0;  // bit j (j < kOwnSolidLights): light j in front of the face, by the margin
};
std::vector<OwnSolid> own_solids(const PrimitiveSet& set, const ClosedSolids& solids,
                                 const std::vector<Light>& lights,
                                 const std::vector<uint8_t>& stops_light, double eps);

// The primitives [first, first + count) a shadow ray may skip.
struct PrimRange {
  int first = 0, count = 0;
  bool has(int prim) const {
    return static_cast<unsigned>(prim - first) < static_cast<unsigned>(count);
  }
};

// What a shadow ray to light j from face `receiver` (-1: none) skips: the
// receiver's own solid, where the light is in front of the face.
inline PrimRange own_solid_skip(const std::vector<OwnSolid>& own, int receiver, int light) {
  if (receiver < 0 || own.empty() || light >= kOwnSolidLights) return {};
  const OwnSolid& o = own[receiver];
  if (!(o.lights >> light & 1)) return {};
  return PrimRange{o.first, o.count};
}

// Whether a convex polyhedron primitive (closed, outward normals, by
// construction) hides its faces turned away from the eye (faces_away): it
// lies wholly deeper than z_near and hither.
bool convex_hides_back_faces(const ConvexPrim& c, const CameraFrame& cam, double z_near);

// The point lies behind the plane dot(normal, p) = offset, normal outward.
inline bool faces_away(const Vec3& normal, double offset, const Vec3& point) {
  return glm::dot(normal, point) - offset < 0;
}

}  // namespace locus
