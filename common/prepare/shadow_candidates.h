// The shadow search of configuration IV (paper §4.1, Fig. 6;
// docs/shadow-volumes.md), built per light on top of the occluders' own
// volumes (shadow_volume.cpp): the hierarchy's boxes and their volumes, the
// front/back relations (per receiving primitive, the occluders that can
// shadow it), the lists of long receivers' slices (ReceiverParts), and the
// Direct entries that the point search (common/trace/shadow_search.h)
// reads. Used by build_shadow_volumes only.
#pragma once

#include <vector>

#include "common/prepare/shadow_volume.h"

namespace locus {

// What the front/back relations use of one primitive: points whose convex
// hull holds it, and the plane of a flat one (polygon, triangle).
struct ReceiverHull {
  std::vector<Vec3> points;
  bool flat = false;
  HalfSpace plane;
};

// What the search needs of the scene, the same for every light.
struct SearchShapes {
  std::vector<ReceiverHull> hulls;  // per primitive
  // Per node of ps.bvh: its box widened to its primitives' hulls.
  std::vector<Aabb> boxes;
  // Per primitive cut into slices: each slice's hull (ReceiverParts).
  std::vector<std::vector<std::vector<Vec3>>> part_hulls;
};

// The boxes and slices for primitives with hulls `hulls`; fills `parts`
// (ShadowVolumes::parts) for the receivers it cuts into slices.
SearchShapes search_shapes(const PreparedScene& ps, std::vector<ReceiverHull> hulls,
                           std::vector<ReceiverParts>& parts);

// Adds to lv (whose occluders' volumes are built) the boxes' volumes
// (node_volume), the candidate lists with their Direct entries, and the
// slices' lists.
void add_search(const PreparedScene& ps, const SearchShapes& shapes, LightVolumes& lv);

}  // namespace locus
