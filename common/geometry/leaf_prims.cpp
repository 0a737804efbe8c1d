#include "common/geometry/leaf_prims.h"

namespace locus {
namespace {

LeafKind leaf_kind(const PrimitiveSet& set, const PrimRef& ref) {
  switch (ref.kind) {
    case PrimKind::kPolygon: {
      const PolygonPrim& p = set.polygons[ref.index];
      const bool small = p.bucket_first.empty() && !p.pts.empty() &&
                         p.pts.size() <= static_cast<size_t>(kLeafPolygonMax);
      return small ? LeafKind::kPolygon : LeafKind::kOther;
    }
    case PrimKind::kTriangle:
      return LeafKind::kTriangle;
    case PrimKind::kSphere:
      return set.spheres[ref.index].frame.identity ? LeafKind::kSphere : LeafKind::kOther;
    case PrimKind::kCone:
      return set.cones[ref.index].frame.identity ? LeafKind::kCone : LeafKind::kOther;
    default:
      return LeafKind::kOther;
  }
}

}  // namespace

std::vector<LeafPrim> build_leaf_prims(const PrimitiveSet& set, const Bvh& bvh,
                                       const std::vector<uint8_t>& stops_light) {
  bool any = false;
  for (int prim : bvh.order) any = any || leaf_kind(set, set.prims[prim]) != LeafKind::kOther;
  if (!any) return {};
  std::vector<LeafPrim> out(bvh.order.size());
  for (size_t slot = 0; slot < bvh.order.size(); ++slot) {
    const int prim = bvh.order[slot];
    const PrimRef& ref = set.prims[prim];
    LeafPrim& lp = out[slot];
    lp.kind = leaf_kind(set, ref);
    lp.stops_light = stops_light[prim];
    lp.object = ref.object;
    switch (lp.kind) {
      case LeafKind::kPolygon: {
        const PolygonPrim& p = set.polygons[ref.index];
        lp.polygon.normal = p.normal;
        lp.polygon.offset = p.offset;
        for (size_t k = 0; k < p.pts.size(); ++k) lp.polygon.pts[k] = p.pts[k];
        lp.n = static_cast<int8_t>(p.pts.size());
        lp.axis_u = static_cast<int8_t>(p.axis_u);
        lp.axis_v = static_cast<int8_t>(p.axis_v);
        break;
      }
      case LeafKind::kTriangle: {
        const TrianglePrim& tr = set.triangles[ref.index];
        lp.triangle = LeafTriangleData{tr.p0, tr.e1, tr.e2, tr.normal};
        lp.index = ref.index;
        break;
      }
      case LeafKind::kSphere: {
        const SpherePrim& s = set.spheres[ref.index];
        lp.sphere = LeafSphereData{s.s.center, s.s.radius};
        break;
      }
      case LeafKind::kCone: {
        const ConePrim& k = set.cones[ref.index];
        lp.cone = LeafConeData{k.c, k.axis};
        break;
      }
      case LeafKind::kOther:
        break;
    }
  }
  return out;
}

}  // namespace locus
