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

// Where the points of a set lie against the plane p moved out by `offset`
// (the value dot(p.m, x) - p.h - offset for x in the set), as far as its
// ball tells: +1 every point's value is > 0, -1 every point's is < 0, 0
// not known (the plane passes through the ball, or no ball). The ball's
// answer needs a margin of 1e-9 of the magnitudes involved beyond the
// radius, far more than the rounding of any point's own product, so it
// never contradicts what the points' products give.
int ball_side(const PointBall& b, const HalfSpace& p, double offset) {
  if (!(b.radius >= 0)) return 0;
  const double d = glm::dot(p.m, b.centre) - p.h - offset;
  const double margin =
      b.radius + 1e-9 * (b.magnitude + b.radius + std::abs(p.h) + std::abs(offset));
  if (d > margin) return 1;
  if (d < -margin) return -1;
  return 0;
}

// The (conservative) test of a volume against a point set: true when no
// point of `pts` can be in volume `v` even with `slack`. `ball` holds the
// points; the answer is the same as without it, found sooner.
bool separated(const VolumeSet& set, int v, const std::vector<Vec3>& pts, const PointBall& ball,
               double slack) {
  const ShadowVolume& vol = set.volumes[v];
  switch (vol.kind) {
    case VolumeKind::kEverywhere:
      return false;
    case VolumeKind::kConvex:
      for (int i = vol.first; i < vol.first + vol.count; ++i) {
        const HalfSpace& p = set.planes[i];
        const int side = ball_side(ball, p, slack);
        if (side > 0) return true;
        if (side < 0) continue;
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

// Can occluder a's volumes (its bound first) reach the hull `pts` (in
// `ball`)?
bool reaches(const LightVolumes& lv, int a, const std::vector<Vec3>& pts, const PointBall& ball) {
  const LightVolumes::Occluder& oc = lv.occluders[a];
  if (oc.bound >= 0 && separated(lv.set, oc.bound, pts, ball, lv.slack)) return false;
  for (int v = oc.first; v < oc.first + oc.count; ++v) {
    if (!separated(lv.set, v, pts, ball, lv.slack)) return true;
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

// Front/back relations (paper §4.1): the occluders that can shadow
// receiver r. An occluder is dropped when its volume misses the receiver's
// hull, or when it lies wholly behind the plane of a flat receiver as seen
// from the light (a face cannot shadow itself). The hierarchy is walked
// with the boxes' volumes against the hull.
std::vector<int> candidate_ids(const PreparedScene& ps, const SearchShapes& shapes,
                               const LightVolumes& lv, int r) {
  std::vector<int> found;
  const ReceiverHull& hr = shapes.hulls[r];
  const PointBall& br = shapes.balls[r];
  const bool flat = hr.flat;
  const HalfSpace& rplane = hr.plane;
  const double lside = flat ? glm::dot(rplane.m, lv.position) - rplane.h : 0.0;
  walk_bvh(
      ps.bvh,
      [&](int ni) { return !separated(lv.set, lv.node_volume[ni], hr.points, br, lv.slack); },
      [&](int a) {
        if (flat && a == r) return true;
        if (!reaches(lv, a, hr.points, br)) return true;
        if (flat && lside != 0) {
          // Shadow-ray origins lie eps on the light's side of the face:
          // an occluder nowhere more than eps / 2 in front of the plane
          // cannot meet their segments.
          const double sgn = lside > 0 ? 1.0 : -1.0;
          const HalfSpace facing{sgn * rplane.m, sgn * rplane.h};
          const int side = ball_side(shapes.balls[a], facing, 0.5 * ps.eps);
          bool in_front = side > 0;
          if (side == 0) {
            for (const Vec3& x : shapes.hulls[a].points) {
              if (sgn * (glm::dot(rplane.m, x) - rplane.h) > 0.5 * ps.eps) {
                in_front = true;
                break;
              }
            }
          }
          if (!in_front) return true;
        }
        found.push_back(a);
        return true;
      });
  std::sort(found.begin(), found.end());
  return found;
}

// The Direct entry of occluder a (CandidateList::Direct).
CandidateList::Direct direct_of(const LightVolumes& lv, int a) {
  CandidateList::Direct d;
  const LightVolumes::Occluder& oc = lv.occluders[a];
  if (oc.bound >= 0 || oc.count != 1) return d;
  const ShadowVolume& vol = lv.set.volumes[oc.first];
  if (vol.kind != VolumeKind::kConvex) return d;
  return CandidateList::Direct{vol.first, vol.count, oc.decides};
}

// Receiver r's list with its Direct entries and, if it is cut into slices,
// the slices' lists: the receiver's candidates whose volumes reach the
// slice's hull (the tests of candidate_ids, on fewer points).
std::unique_ptr<CandidateList> make_candidate_list(const PreparedScene& ps,
                                                   const SearchShapes& shapes,
                                                   const LightVolumes& lv, int r) {
  auto list = std::make_unique<CandidateList>();
  list->ids = candidate_ids(ps, shapes, lv, r);
  list->direct.reserve(list->ids.size());
  for (const int a : list->ids) list->direct.push_back(direct_of(lv, a));
  const auto& hulls = shapes.part_hulls[r];
  if (hulls.empty()) return list;
  list->part_first.assign(1, 0);
  for (size_t q = 0; q < hulls.size(); ++q) {
    for (size_t k = 0; k < list->ids.size(); ++k) {
      if (!reaches(lv, list->ids[k], hulls[q], shapes.part_balls[r][q])) continue;
      list->part_ids.push_back(list->ids[k]);
      list->part_direct.push_back(list->direct[k]);
    }
    list->part_first.push_back(static_cast<int>(list->part_ids.size()));
  }
  return list;
}

}  // namespace

PointBall ball_of(const std::vector<Vec3>& pts) {
  PointBall b;
  if (pts.empty()) return b;
  Aabb box;
  for (const Vec3& x : pts) box.extend(x);
  b.centre = box.centre();
  double r2 = 0;
  for (const Vec3& x : pts) {
    const Vec3 d = x - b.centre;
    r2 = std::max(r2, glm::dot(d, d));
  }
  // Widened by a relative 1e-9 for the rounding of the distances.
  b.radius = std::sqrt(r2) * (1.0 + 1e-9);
  b.magnitude = std::max(max_component(glm::abs(box.lo)), max_component(glm::abs(box.hi)));
  if (!std::isfinite(b.radius) || !std::isfinite(b.magnitude)) b.radius = -1;
  return b;
}

SearchShapes search_shapes(const PreparedScene& ps, std::vector<ReceiverHull> hulls,
                           std::vector<ReceiverParts>& parts) {
  SearchShapes s;
  s.boxes = search_boxes(ps.bvh, hulls);
  s.balls.reserve(hulls.size());
  for (const ReceiverHull& h : hulls) s.balls.push_back(ball_of(h.points));
  s.hulls = std::move(hulls);
  s.part_hulls = cut_receivers(ps, parts);
  s.part_balls.resize(s.part_hulls.size());
  for (size_t r = 0; r < s.part_hulls.size(); ++r) {
    for (const std::vector<Vec3>& hull : s.part_hulls[r]) s.part_balls[r].push_back(ball_of(hull));
  }
  return s;
}

// The hierarchy's boxes (paper §4.1): a point outside a box's volume is
// shadowed by nothing in the box. Each box is widened to hold its
// occluders' own volumes' outlines (a curved body's bounding polyhedron
// reaches beyond the body's box), so a box's volume holds every volume
// below it and pruning by boxes never drops an interval.
void add_box_volumes(const SearchShapes& shapes, int begin, int end, LightVolumes& lv) {
  // make_box's faces and vertices, refilled for each box (no allocation per
  // box).
  const Polyhedron unit = make_box(Vec3(0.0), Vec3(1.0));
  std::vector<std::vector<Vec3>> faces(unit.faces.size());
  std::vector<Vec3> corners(unit.vertices.size());
  std::vector<HalfSpace> planes(6);
  for (int b = begin; b < end; ++b) {
    const Aabb& vb = shapes.boxes[b];
    const Vec3 lo = glm::min(vb.lo, vb.hi), hi = glm::max(vb.lo, vb.hi);
    for (size_t i = 0; i < corners.size(); ++i) {
      corners[i] = Vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    }
    for (size_t k = 0; k < faces.size(); ++k) {
      faces[k].resize(unit.faces[k].size());
      for (size_t i = 0; i < faces[k].size(); ++i) faces[k][i] = corners[unit.faces[k][i]];
    }
    planes = {{Vec3(-1, 0, 0), -vb.lo.x}, {Vec3(1, 0, 0), vb.hi.x},   {Vec3(0, -1, 0), -vb.lo.y},
              {Vec3(0, 1, 0), vb.hi.y},   {Vec3(0, 0, -1), -vb.lo.z}, {Vec3(0, 0, 1), vb.hi.z}};
    lv.node_volume.push_back(
        add_polyhedron_volume(lv.set, faces, planes, lv.position, false, &corners));
  }
}

const CandidateList& receiver_candidates(const PreparedScene& ps, int light, int receiver) {
  const LightVolumes& lv = ps.volumes->lights[light];
  if (const CandidateList* list = lv.candidates.find(receiver)) return *list;
  return lv.candidates.install(receiver,
                               make_candidate_list(ps, *ps.volumes->shapes, lv, receiver));
}

CandidateTable::CandidateTable(size_t receivers)
    : slots_(new std::atomic<const CandidateList*>[receivers]), size_(receivers) {
  for (size_t i = 0; i < size_; ++i) slots_[i].store(nullptr, std::memory_order_relaxed);
}

CandidateTable::CandidateTable(CandidateTable&& o) noexcept
    : slots_(std::move(o.slots_)), size_(o.size_) {
  o.size_ = 0;
}

CandidateTable& CandidateTable::operator=(CandidateTable&& o) noexcept {
  if (this != &o) {
    clear();
    slots_ = std::move(o.slots_);
    size_ = o.size_;
    o.size_ = 0;
  }
  return *this;
}

CandidateTable::~CandidateTable() { clear(); }

void CandidateTable::clear() {
  for (size_t i = 0; i < size_; ++i) delete slots_[i].load(std::memory_order_acquire);
  slots_.reset();
  size_ = 0;
}

const CandidateList& CandidateTable::install(int receiver,
                                             std::unique_ptr<CandidateList> list) const {
  const CandidateList* expected = nullptr;
  if (slots_[receiver].compare_exchange_strong(expected, list.get(), std::memory_order_acq_rel,
                                               std::memory_order_acquire)) {
    return *list.release();
  }
  return *expected;  // another thread's, the same list
}

}  // namespace locus
