// The shadow search of configuration IV (paper §4.1): the boxes' volumes,
// the front/back relations and the slices' lists, per light, on top of the
// occluders' volumes of shadow_volume.cpp (shadow_candidates.h).
#include "common/prepare/shadow_candidates.h"

#include <algorithm>
#include <cmath>

#include "common/prepare/prepared.h"
#include "common/scene/polyhedron.h"

namespace locus {
namespace {

// The (conservative) test of a volume against a point set: true when no
// point of `pts` can be in volume `v` even with `slack`.
bool separated(const VolumeSet& set, int v, const std::vector<Vec3>& pts, double slack) {
  const ShadowVolume& vol = set.volumes[v];
  switch (vol.kind) {
    case VolumeKind::kEverywhere:
      return false;
    case VolumeKind::kConvex:
      for (int i = vol.first; i < vol.first + vol.count; ++i) {
        const HalfSpace& p = set.planes[i];
        bool all_out = true;
        for (const Vec3& x : pts) {
          if (!(glm::dot(p.m, x) - p.h > slack)) {
            all_out = false;
            break;
          }
        }
        if (all_out) return true;
      }
      return false;
    case VolumeKind::kOutside:
      // Every point strictly inside the occluder: none is shadowed by it.
      for (const Vec3& x : pts) {
        for (int i = vol.first; i < vol.first + vol.count; ++i) {
          if (!(glm::dot(set.planes[i].m, x) - set.planes[i].h < -slack)) return false;
        }
      }
      return true;
  }
  return false;
}

// Can occluder a's volumes (its bound first) reach the hull `pts`?
bool reaches(const LightVolumes& lv, int a, const std::vector<Vec3>& pts) {
  const LightVolumes::Occluder& oc = lv.occluders[a];
  if (oc.bound >= 0 && separated(lv.set, oc.bound, pts, lv.slack)) return false;
  for (int v = oc.first; v < oc.first + oc.count; ++v) {
    if (!separated(lv.set, v, pts, lv.slack)) return true;
  }
  return false;
}

// The boxes of the shadow search: the hierarchy's, widened to the hulls
// (children follow their parent in bvh.nodes).
std::vector<Aabb> search_boxes(const Bvh& bvh, const std::vector<ReceiverHull>& hulls) {
  std::vector<Aabb> boxes(bvh.nodes.size());
  for (int ni = static_cast<int>(bvh.nodes.size()) - 1; ni >= 0; --ni) {
    const BvhNode& node = bvh.nodes[ni];
    Aabb b = node.box;
    if (node.count > 0) {
      for (int k = node.first; k < node.first + node.count; ++k) {
        for (const Vec3& x : hulls[bvh.order[k]].points) b.extend(x);
      }
    } else {
      b.extend(boxes[ni + 1]);
      b.extend(boxes[node.first]);
    }
    boxes[ni] = b;
  }
  return boxes;
}

// Receivers cut into slices (ReceiverParts): untransformed cones at least
// two diameters long, one slice per diameter, at most kMaxParts. Each
// slice's hull: squares circumscribing the larger end circle, at the
// slice's ends moved out by more than the shadow-ray offset (an origin eps
// off the surface may lie just past a slice boundary). Returns the slices'
// hulls per primitive.
std::vector<std::vector<std::vector<Vec3>>> cut_receivers(const PreparedScene& ps,
                                                          std::vector<ReceiverParts>& parts) {
  constexpr int kMaxParts = 8;
  const PrimitiveSet& set = ps.prims;
  const int n = static_cast<int>(set.prims.size());
  std::vector<std::vector<std::vector<Vec3>>> part_hulls(n);
  parts.resize(n);
  int slots = 0;
  for (int i = 0; i < n; ++i) {
    const PrimRef& ref = set.prims[i];
    if (ref.kind != PrimKind::kCone || !set.cones[ref.index].frame.identity) continue;
    const Cone& c = set.cones[ref.index].c;
    const Vec3 d = c.apex - c.base;
    const double len = glm::length(d);
    const double rmax = std::max(std::abs(c.base_radius), std::abs(c.apex_radius));
    if (!(len > 0) || !(rmax > 0) || !std::isfinite(len)) continue;
    const int k = clamped_floor(len / (2.0 * rmax), 0, kMaxParts);
    if (k < 2) continue;
    ReceiverParts& rp = parts[i];
    rp.base = c.base;
    rp.scaled_axis = d / (len * len);
    rp.count = k;
    rp.slot = slots;
    slots += k;
    const Vec3 a = d / len;
    const Vec3 u = any_perpendicular(a), v = glm::cross(a, u);
    const double margin = (8.0 * ps.eps + 1e-9 * (len + max_component(glm::abs(c.base)))) / len;
    const double rho = rmax * (1.0 + 1e-9);  // the larger end's square all along
    for (int q = 0; q < k; ++q) {
      std::vector<Vec3> pts;
      for (const double t :
           {static_cast<double>(q) / k - margin, static_cast<double>(q + 1) / k + margin}) {
        const Vec3 centre = c.base + t * d;
        for (const double su : {-1.0, 1.0}) {
          for (const double sw : {-1.0, 1.0}) pts.push_back(centre + rho * (su * u + sw * v));
        }
      }
      part_hulls[i].push_back(std::move(pts));
    }
  }
  return part_hulls;
}

// The hierarchy's boxes (paper §4.1): a point outside a box's volume is
// shadowed by nothing in the box. Each box is widened to hold its
// occluders' own volumes' outlines (a curved body's bounding polyhedron
// reaches beyond the body's box), so a box's volume holds every volume
// below it and pruning by boxes never drops an interval.
void add_box_volumes(const std::vector<Aabb>& boxes, LightVolumes& lv) {
  for (const Aabb& vb : boxes) {
    const Polyhedron box = make_box(vb.lo, vb.hi);
    std::vector<std::vector<Vec3>> faces;
    for (const auto& face : box.faces) {
      std::vector<Vec3> pts;
      for (int v : face) pts.push_back(box.vertices[v]);
      faces.push_back(std::move(pts));
    }
    const Vec3 lo = vb.lo, hi = vb.hi;
    const std::vector<HalfSpace> planes = {{Vec3(-1, 0, 0), -lo.x}, {Vec3(1, 0, 0), hi.x},
                                           {Vec3(0, -1, 0), -lo.y}, {Vec3(0, 1, 0), hi.y},
                                           {Vec3(0, 0, -1), -lo.z}, {Vec3(0, 0, 1), hi.z}};
    lv.node_volume.push_back(add_polyhedron_volume(lv.set, faces, planes, lv.position, false));
  }
}

// Front/back relations (paper §4.1): the occluders that can shadow each
// primitive. An occluder is dropped when its volume misses the primitive's
// hull, or when it lies wholly behind the plane of a flat primitive as seen
// from the light (a face cannot shadow itself). The hierarchy is walked
// with the boxes' volumes against the hull.
void add_candidate_lists(const PreparedScene& ps, const std::vector<ReceiverHull>& hulls,
                         LightVolumes& lv) {
  const int n = static_cast<int>(ps.prims.prims.size());
  lv.candidate_first.assign(n + 1, 0);
  std::vector<int> found;
  for (int r = 0; r < n; ++r) {
    found.clear();
    const ReceiverHull& hr = hulls[r];
    const bool flat = hr.flat;
    const HalfSpace& rplane = hr.plane;
    const double lside = flat ? glm::dot(rplane.m, lv.position) - rplane.h : 0.0;
    walk_bvh(
        ps.bvh, [&](int ni) { return !separated(lv.set, lv.node_volume[ni], hr.points, lv.slack); },
        [&](int a) {
          if (flat && a == r) return true;
          if (!reaches(lv, a, hr.points)) return true;
          if (flat && lside != 0) {
            // Shadow-ray origins lie eps on the light's side of the face:
            // an occluder nowhere more than eps / 2 in front of the plane
            // cannot meet their segments.
            const double sgn = lside > 0 ? 1.0 : -1.0;
            bool in_front = false;
            for (const Vec3& x : hulls[a].points) {
              if (sgn * (glm::dot(rplane.m, x) - rplane.h) > 0.5 * ps.eps) {
                in_front = true;
                break;
              }
            }
            if (!in_front) return true;
          }
          found.push_back(a);
          return true;
        });
    std::sort(found.begin(), found.end());
    lv.candidates.insert(lv.candidates.end(), found.begin(), found.end());
    lv.candidate_first[r + 1] = static_cast<int>(lv.candidates.size());
  }
}

// The Direct entry of each candidate (LightVolumes::Direct).
void add_candidate_direct(LightVolumes& lv) {
  auto direct_of = [&](int a) {
    LightVolumes::Direct d;
    const LightVolumes::Occluder& oc = lv.occluders[a];
    if (oc.bound >= 0 || oc.count != 1) return d;
    const ShadowVolume& vol = lv.set.volumes[oc.first];
    if (vol.kind != VolumeKind::kConvex) return d;
    return LightVolumes::Direct{vol.first, vol.count, oc.decides};
  };
  lv.candidate_direct.resize(lv.candidates.size());
  for (size_t k = 0; k < lv.candidates.size(); ++k)
    lv.candidate_direct[k] = direct_of(lv.candidates[k]);
}

// The slices' lists: the receiver's candidates whose volumes reach the
// slice's hull (the tests of add_candidate_lists, on fewer points).
void add_part_lists(const std::vector<std::vector<std::vector<Vec3>>>& part_hulls,
                    LightVolumes& lv) {
  lv.part_first.assign(1, 0);
  for (int r = 0; r < static_cast<int>(part_hulls.size()); ++r) {
    for (const std::vector<Vec3>& hull : part_hulls[r]) {
      for (int k = lv.candidate_first[r]; k < lv.candidate_first[r + 1]; ++k) {
        const int a = lv.candidates[k];
        if (!reaches(lv, a, hull)) continue;
        lv.part_candidates.push_back(a);
        lv.part_direct.push_back(lv.candidate_direct[k]);
      }
      lv.part_first.push_back(static_cast<int>(lv.part_candidates.size()));
    }
  }
}

}  // namespace

SearchShapes search_shapes(const PreparedScene& ps, std::vector<ReceiverHull> hulls,
                           std::vector<ReceiverParts>& parts) {
  SearchShapes s;
  s.boxes = search_boxes(ps.bvh, hulls);
  s.hulls = std::move(hulls);
  s.part_hulls = cut_receivers(ps, parts);
  return s;
}

void add_search(const PreparedScene& ps, const SearchShapes& shapes, LightVolumes& lv) {
  add_box_volumes(shapes.boxes, lv);
  add_candidate_lists(ps, shapes.hulls, lv);
  add_candidate_direct(lv);
  add_part_lists(shapes.part_hulls, lv);
}

}  // namespace locus
