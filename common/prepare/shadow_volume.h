// Shadow volumes and the shadow search of configuration IV (paper §4.1,
// Fig. 6; METHOD.md §4 step 2 and §7; docs/shadow-volumes.md).
//
// Per light, before any row is rendered:
// - every occluder gets a shadow volume: the region behind it as seen from
//   the light, bounded by the planes through the light and its silhouette
//   edges and capped by the occluder's own light-facing faces. A point
//   whose straight segment to the light meets a convex occluder lies in
//   that volume, and only such points do, so an opaque polygon, triangle or
//   convex polyhedron decides by containment alone, without a ray. Curved
//   bodies (and CSG) get the volume of their bounding polyhedra: a point
//   inside it gets an exact test against the body. A concave polygon is cut
//   into triangles, one volume each;
// - every box of the hierarchy gets the volume of the box: a point outside
//   it is shadowed by nothing in the box;
// - every primitive gets the list of occluders that can shadow it (the
//   front/back relations of §4.1).
//
// This file's functions build them: shadow_volume.cpp the occluders'
// volumes, shadow_candidates.cpp the boxes' volumes and the lists. Rows then
// find the shadows of their spans (SpanShadows in
// common/scan/span_shadows.h, paper §3.2 step 2), and points reached by
// secondary rays search the hierarchy (volume_transmittance,
// common/trace/shadow_search.h). Both give exactly what a shadow ray gives
// (Tracer::transmittance), but at points within rounding of a shadow
// boundary.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/base/math.h"
#include "common/base/params.h"
#include "common/geometry/geometry.h"

namespace locus {

class PreparedScene;  // common/prepare/prepared.h

// The half-space m . x <= h (m unit).
struct HalfSpace {
  Vec3 m;
  double h = 0;
};

enum class VolumeKind : uint8_t {
  kConvex,      // the points inside every plane
  kOutside,     // the light lies inside a convex occluder: the points outside it
  kEverywhere,  // no volume could be formed: every point is a candidate
};

struct ShadowVolume {
  VolumeKind kind = VolumeKind::kConvex;
  int first = 0;  // planes [first, first + count) of the VolumeSet
  int count = 0;
};

// Volumes and their planes, stored flat.
struct VolumeSet {
  std::vector<HalfSpace> planes;
  std::vector<ShadowVolume> volumes;
  // Per plane, its products with the camera frame, for scanline intervals
  // (span_shadows.cpp): m.u, m.v, m.w and m.E - h (E: the eye).
  struct CameraDots {
    double mu, mv, mw, me;
  };
  std::vector<CameraDots> cam;

  // Is p in volume v? Every plane is moved outward by `slack` (0: the exact
  // volume; > 0: a conservative one, for culling and candidates).
  bool contains(int v, const Vec3& p, double slack) const;
  // Is p inside planes [first, first + count), each moved out by `slack`?
  // (contains() for a kConvex volume.)
  bool inside_planes(int first, int count, const Vec3& p, double slack) const {
    for (int i = first; i < first + count; ++i) {
      if (glm::dot(planes[i].m, p) - planes[i].h > slack) return false;
    }
    return true;
  }
};

// The shadow volume of a convex polyhedron (faces listed as outlines, any
// winding, with their outward planes) seen from `light`, appended to `out`.
// When no face faces the light (the light inside or on the polyhedron), the
// volume is kOutside if `solid` (the points whose segment to the light
// crosses the surface of a solid convex occluder: those outside it), else
// kEverywhere. `corners`, if given, are the polyhedron's vertices, each
// once (the faces repeat them); the volume is the same with or without
// them. Returns the index of the volume.
int add_polyhedron_volume(VolumeSet& out, const std::vector<std::vector<Vec3>>& faces,
                          const std::vector<HalfSpace>& face_planes, const Vec3& light, bool solid,
                          const std::vector<Vec3>* corners = nullptr);

// A planar outline (normal n) cut into convex pieces, as index lists into
// its vertices: itself if it is convex; else an ear-clipping triangulation
// whose triangles are merged while they stay convex. nullopt if the outline
// is not simple (self-intersecting), so it cannot be cut.
using ConvexPieces = std::vector<std::vector<int>>;
std::optional<ConvexPieces> convex_pieces(const std::vector<Vec3>& verts, const Vec3& n);

// The shadow volumes of a planar polygon (plane n . x = d) seen from
// `light`, one per convex piece; none if the light lies in its plane (the
// polygon is seen edge-on and casts nothing). Planes through an edge shared
// by two pieces are exact negations of each other, so no point between two
// pieces escapes both. Returns the number of volumes appended, or -1 if the
// outline could not be cut into convex pieces.
int add_polygon_volumes(VolumeSet& out, const std::vector<Vec3>& verts, const Vec3& n, double d,
                        const Vec3& light);
int add_pieces_volumes(VolumeSet& out, const std::vector<Vec3>& verts, const ConvexPieces& pieces,
                       const Vec3& n, double d, const Vec3& light);

// One receiving primitive's front/back relations from one light (paper
// §4.1): the occluders that can shadow it, increasing, and, for a receiver
// cut into slices (ReceiverParts), those of each slice.
struct CandidateList {
  // Where the occluder is one convex volume with no bound (most curved
  // bodies and polygons), its planes, so the search reads them without two
  // dependent lookups; count < 0 otherwise.
  struct Direct {
    int first = 0, count = -1;
    bool decides = false;  // the occluder's
  };
  std::vector<int> ids;
  std::vector<Direct> direct;  // per entry of ids
  // Slice q's occluders (a subset of ids): part_ids[part_first[q],
  // part_first[q + 1]), increasing, with their Direct entries.
  std::vector<int> part_first;
  std::vector<int> part_ids;
  std::vector<Direct> part_direct;
};

// Per receiving primitive, its CandidateList, made the first time a row
// asks for it (receiver_candidates, shadow_candidates.h): a frame's rows
// reach only some of the primitives, often a third or less of a big
// scene's. Any thread may make a list; the first one installed is kept,
// and every thread makes the same one, so neither the thread nor the order
// changes anything a row computes.
class CandidateTable {
 public:
  CandidateTable() = default;
  explicit CandidateTable(size_t receivers);
  CandidateTable(CandidateTable&& o) noexcept;
  CandidateTable& operator=(CandidateTable&& o) noexcept;
  ~CandidateTable();

  const CandidateList* find(int receiver) const {
    return slots_[receiver].load(std::memory_order_acquire);
  }
  // Keeps `list` as receiver's unless another thread installed one first;
  // returns the one kept.
  const CandidateList& install(int receiver, std::unique_ptr<CandidateList> list) const;

 private:
  void clear();
  std::unique_ptr<std::atomic<const CandidateList*>[]> slots_;
  size_t size_ = 0;
};

// What one light's shadow search needs.
struct LightVolumes {
  Vec3 position;
  VolumeSet set;
  // Per primitive (index into PrimitiveSet::prims): its volumes
  // set.volumes[first, first + count); `decides` when containment alone
  // gives t_pj = 0 (an opaque polygon, triangle or convex polyhedron),
  // otherwise a point inside needs the exact segment test (curved bodies,
  // CSG, transparent occluders).
  struct Occluder {
    int first = 0, count = 0;
    bool decides = false;
    int bound = -1;  // a volume holding all of them, tested first (concave polygons)
  };
  std::vector<Occluder> occluders;
  std::vector<int> node_volume;  // per BVH node: index into set.volumes
  // Per receiving primitive: the occluders that can shadow it, made when
  // first asked for (receiver_candidates).
  CandidateTable candidates;
  // Slack of the conservative tests (boxes, bounding polyhedra, transparent
  // occluders, candidates): beyond the offset of shadow-ray origins
  // (PreparedScene::eps) and far beyond rounding.
  double slack = 0;
};

// A long cone or cylinder as a receiver is cut into `count` slices along
// its axis, each with its own candidate list (a point near one end is not
// shadowed by what can only reach the other). A shadow-ray origin o lies in
// slice floor(count * dot(o - base, scaled_axis)), clamped.
struct ReceiverParts {
  Vec3 base{0.0}, scaled_axis{0.0};  // (apex - base) / |apex - base|^2
  int count = 0;                     // 0: not cut
};

struct SearchShapes;  // common/prepare/shadow_candidates.h

struct ShadowVolumes {
  std::vector<LightVolumes> lights;
  std::vector<ReceiverParts> parts;  // per primitive (search only)
  // What the candidate lists are made from (search only).
  std::shared_ptr<const SearchShapes> shapes;
  // Configuration IV: the boxes' volumes (node_volume) and the front/back
  // relations (candidates) are built, and points reached by secondary rays
  // search them (volume_transmittance). Otherwise (II, III) only the
  // occluders' volumes exist: each span meets every one of them, and
  // secondary points cast shadow rays.
  bool search = false;
};

// Built at prepare time for --method local: with `search` (configuration
// IV, --boxes eye+shadow) the hierarchy's volumes and the candidate lists
// too. Needs ps.prims, and ps.bvh if `search`. Runs on up to `threads`
// threads (parallel_for, common/base/parallel.h): the occluders' shapes
// and the receivers' hulls by chunks of primitives, then every light's
// volumes by chunks of primitives and of boxes, joined in order; the
// result is the same, bit for bit, for any count.
ShadowVolumes build_shadow_volumes(const PreparedScene& ps, bool search, int threads = 1);

// Whether prims[prim]'s material lets no light through.
bool is_opaque(const PreparedScene& ps, int prim);

}  // namespace locus
