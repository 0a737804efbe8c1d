// The shadow search of configuration IV (paper §4.1, Fig. 6;
// docs/shadow-volumes.md), built per light on top of the occluders' own
// volumes (shadow_volume.cpp): the hierarchy's boxes and their volumes,
// built with the frame, and the front/back relations (per receiving
// primitive, the occluders that can shadow it, with the lists of long
// receivers' slices, ReceiverParts, and the Direct entries that the
// searches read), made when a row first asks for them.
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

// A ball holding a point set, for a quick first answer to "is every point
// beyond this plane" (ball_side in shadow_candidates.cpp): a plane clear of
// the ball, by more than any rounding of the points' own products, answers
// for every point at once; only a plane through the ball needs the points.
struct PointBall {
  Vec3 centre{0.0};
  double radius = -1;    // < 0: no ball (empty set): always look at the points
  double magnitude = 0;  // the largest coordinate magnitude of the points
};
PointBall ball_of(const std::vector<Vec3>& pts);

// What the search needs of the scene, the same for every light.
struct SearchShapes {
  std::vector<ReceiverHull> hulls;  // per primitive
  std::vector<PointBall> balls;     // per primitive: its hull's points
  // Per node of ps.bvh: its box widened to its primitives' hulls.
  std::vector<Aabb> boxes;
  // Per primitive cut into slices: each slice's hull (ReceiverParts).
  std::vector<std::vector<std::vector<Vec3>>> part_hulls;
  std::vector<std::vector<PointBall>> part_balls;
};

// The boxes and slices for primitives with hulls `hulls`; fills `parts`
// (ShadowVolumes::parts) for the receivers it cuts into slices.
SearchShapes search_shapes(const PreparedScene& ps, std::vector<ReceiverHull> hulls,
                           std::vector<ReceiverParts>& parts);

// Appends to lv the volumes of the search boxes [begin, end) (shapes.boxes,
// one per node of ps.bvh), and their indices to lv.node_volume. Boxes cut
// into ranges and appended range after range (build_shadow_volumes) give
// what all at once gives.
void add_box_volumes(const SearchShapes& shapes, int begin, int end, LightVolumes& lv);

// Receiver `receiver`'s front/back relations from light `light` (paper
// §4.1; configuration IV, ps.volumes->search): made from ps.volumes->shapes
// the first time any thread asks, the same list whichever thread does.
const CandidateList& receiver_candidates(const PreparedScene& ps, int light, int receiver);

}  // namespace locus
