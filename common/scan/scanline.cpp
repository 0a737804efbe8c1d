#include "common/scan/scanline.h"

#include <algorithm>
#include <cmath>

#include "common/prepare/prepared.h"

namespace locus {
FaceDepth face_depth(const ScanFace& f, const CameraFrame& cam, const Vec3& eye) {
  return FaceDepth{glm::dot(f.normal, cam.w), glm::dot(f.normal, cam.v), glm::dot(f.normal, cam.u),
                   f.offset - glm::dot(f.normal, eye)};
}

LineDepth line_depth(const FaceDepth& p, const CameraFrame& cam, double b) {
  // 1/s = (nw + a nu) / num with a = (2x / width - 1) tan_half aspect.
  const double nw = p.nw + b * p.nv;
  const double k = cam.tan_half * cam.aspect;
  return LineDepth{(nw - k * p.nu) / p.num, 2.0 * k * p.nu / (cam.width * p.num)};
}

void outline_crossings(const ScanFace& f, double y, std::vector<double>& xs) {
  xs.clear();
  const size_t n = f.outline.size();
  for (size_t k = 0, next = 1; k < n; ++k, next = next + 1 == n ? 0 : next + 1) {
    Vec2 p = f.outline[k], q = f.outline[next];
    if (p.y > q.y || (p.y == q.y && p.x > q.x)) std::swap(p, q);
    if (!(p.y <= y && y < q.y)) continue;
    xs.push_back(p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y));
  }
  if (xs.size() == 2) {
    if (xs[1] < xs[0]) std::swap(xs[0], xs[1]);  // a convex outline: the usual case
  } else {
    std::sort(xs.begin(), xs.end());
  }
}

std::optional<Crossing> hit_on_face(const PreparedScene& ps, const ScanFace& f, const Ray& ray) {
  // The face's primitive from its leaf copy where it has one (leaf_prims.h:
  // the same answer, bit for bit, from one place in memory instead of
  // three; on SPD tetra level 9 every figure of a pixel is a face of its
  // own, and these tests, scattered over 262,144 primitives, were 9% of
  // the render at --aa 4).
  std::optional<Crossing> hit;
  if (const LeafPrim* lp = ps.leaf_prim_of(f.prim)) {
    Crossing c;
    if (leaf_nearest(*lp, ray, ps.camera.hither, 1e300, &c)) hit = c;
  } else {
    hit = intersect_nearest(ps.prims, f.prim, ray, ps.camera.hither, 1e300);
  }
  if (hit && !on_face(f, ray.origin, ray.dir, hit->t)) hit.reset();
  return hit;
}

namespace {

// Sorts v by `less`, an order that follows x_of (less(a, c) only where
// x_of(a) <= x_of(c)), for x in [0, width]: counted into one bucket per
// pixel column, then finished by insertion, which moves items only within
// their column. The result is std::sort's for any input; a sample line's
// intervals are a few per column, so this takes linear time where
// std::sort took most of the line's set-up (SPD tetra level 9). A column
// holding more than kColumnSortMax items is sorted by std::sort first (the
// insertion then moves nothing there). Fewer items than a quarter of the
// columns are left to std::sort: clearing and summing the columns' counts
// cost more there (SPD tetra level 7, b_desk). Each item's column is
// computed once (`cols`).
template <class T, class X, class Less>
void column_sort(std::vector<T>& v, std::vector<T>& tmp, std::vector<int>& count,
                 std::vector<int>& cols, int width, X&& x_of, Less&& less) {
  constexpr int kColumnSortMax = 32;
  const size_t n = v.size();
  if (n < 2) return;
  if (n * 4 < static_cast<size_t>(width)) {
    // Few items: the columns' counts would cost more than they save.
    std::sort(v.begin(), v.end(), less);
    return;
  }
  count.assign(width + 1, 0);
  cols.resize(n);
  int most = 0;
  for (size_t i = 0; i < n; ++i) {
    cols[i] = clamped_floor(x_of(v[i]), 0, width - 1);
    most = std::max(most, ++count[cols[i] + 1]);
  }
  for (int c = 0; c < width; ++c) count[c + 1] += count[c];
  tmp.resize(n);
  for (size_t i = 0; i < n; ++i) tmp[count[cols[i]]++] = v[i];
  if (most > kColumnSortMax) {
    // count[c] is now where column c ends.
    for (int c = 0, begin = 0; c < width; begin = count[c++]) {
      if (count[c] - begin > kColumnSortMax)
        std::sort(tmp.begin() + begin, tmp.begin() + count[c], less);
    }
  }
  for (size_t i = 1; i < n; ++i) {
    const T e = tmp[i];
    size_t k = i;
    for (; k > 0 && less(e, tmp[k - 1]); --k) tmp[k] = tmp[k - 1];
    tmp[k] = e;
  }
  v.swap(tmp);
}

double face_t(const ScanFace& f, const Vec3& origin, double den) {
  return (f.offset - glm::dot(f.normal, origin)) / den;
}
}  // namespace

Vec3 face_point(const ScanFace& f, const Vec3& origin, const Vec3& dir) {
  return origin + face_t(f, origin, glm::dot(f.normal, dir)) * dir;
}

bool on_face(const ScanFace& f, const Vec3& origin, const Vec3& dir, double t) {
  const double den = glm::dot(f.normal, dir);
  if (den == 0) return false;
  const double tp = face_t(f, origin, den);
  return std::abs(tp - t) <= 1e-7 * std::max(std::abs(tp), std::abs(t));
}

bool wins_tie(const ScanScene& scan, int fi, int fj) {
  const ScanFace& f = scan.faces[fi];
  const ScanFace& c = scan.faces[fj];
  return (f.curved && !c.curved) ||
         (f.curved == c.curved && (f.prim < c.prim || (f.prim == c.prim && fi < fj)));
}

RowVisibility visible_faces(const ScanScene& scan, const CameraFrame& cam, const Vec3& eye,
                            int row) {
  const int width = cam.width;
  RowVisibility vis;
  vis.face.assign(width, -1);
  vis.s.assign(width, 0.0);
  const double yc = row + 0.5;
  // Sample direction (unnormalised): w + a(x) u + b v (SHADING.md).
  const double b = (1.0 - 2.0 * yc / cam.height) * cam.tan_half;
  std::vector<double> xs;
  for (int fi : scan.rows[row]) {
    const ScanFace& f = scan.faces[fi];
    outline_crossings(f, yc, xs);
    const FaceDepth p = face_depth(f, cam, eye);
    const double nw = p.nw + b * p.nv;
    const double nu = p.nu;
    const double num = p.num;
    for (size_t k = 0; k + 1 < xs.size(); k += 2) {
      // Pixel centres i + 0.5 in [xl, xr).
      const int i0 = clamped_ceil(xs[k] - 0.5, 0, width);
      const int i1 = clamped_ceil(xs[k + 1] - 0.5, 0, width);
      for (int i = i0; i < i1; ++i) {
        const double a = (2.0 * (i + 0.5) / width - 1.0) * cam.tan_half * cam.aspect;
        const double s = num / (nw + a * nu);
        if (!(s > 0)) continue;
        const int cur = vis.face[i];
        bool take = cur < 0 || s < vis.s[i] * (1.0 - kTieRel);
        if (!take && cur >= 0 && s <= vis.s[i] * (1.0 + kTieRel)) {
          // Coincident: a bounding polyhedron wins (its pixel is traced, and
          // the trace finds the truth); else the first-defined surface.
          take = wins_tie(scan, fi, cur);
        }
        if (take) {
          vis.face[i] = fi;
          vis.s[i] = s;
        }
      }
    }
  }
  for (int i = 0; i < width; ++i) {
    if (i == 0 || vis.face[i] != vis.face[i - 1]) ++vis.spans;
  }
  return vis;
}

void visible_segments(const ScanScene& scan, const CameraFrame& cam, double y,
                      const std::vector<int>& faces, VisibleScratch& scratch,
                      std::vector<VisibleSegment>& out) {
  using Interval = DepthInterval;
  const double b = (1.0 - 2.0 * y / cam.height) * cam.tan_half;
  const double width = cam.width;
  std::vector<Interval>& ivs = scratch.ivs;
  std::vector<double>& xs = scratch.xs;
  ivs.clear();
  out.clear();
  // The faces' y extents side by side, and the parts of their depth along
  // a line that do not depend on the line, gathered once for the sample
  // lines of a row (its faces come in one list): most faces of a row miss
  // a given line where they are smaller than a pixel, and one that does
  // not meets several.
  if (scratch.y_of != &faces || scratch.y_scene != &scan) {
    scratch.y_of = &faces;
    scratch.y_scene = &scan;
    scratch.row_faces.clear();
    for (int fi : faces) {
      const ScanFace& f = scan.faces[fi];
      scratch.row_faces.push_back({f.ymin, f.ymax, face_depth(f, cam, cam.from)});
    }
  }
  for (size_t k = 0; k < faces.size(); ++k) {
    const VisibleScratch::RowFace& rf = scratch.row_faces[k];
    if (!(rf.ymin <= y && y < rf.ymax)) continue;
    const int fi = faces[k];
    const ScanFace& f = scan.faces[fi];
    outline_crossings(f, y, xs);
    const LineDepth d = line_depth(rf.depth, cam, b);
    for (size_t k = 0; k + 1 < xs.size(); k += 2) {
      const double xl = std::max(0.0, xs[k]), xr = std::min(width, xs[k + 1]);
      if (xr > xl) ivs.push_back(Interval{xl, xr, fi, d});
    }
  }
  // The intervals by (xl, face), a total order (a face's intervals on one
  // line are disjoint): sorted as small keys, then moved once.
  using Key = VisibleScratch::Key;
  std::vector<Key>& keys = scratch.keys;
  keys.clear();
  for (size_t k = 0; k < ivs.size(); ++k)
    keys.push_back(Key{ivs[k].xl, ivs[k].face, static_cast<int>(k)});
  column_sort(
      keys, scratch.keys_tmp, scratch.count, scratch.cols, cam.width,
      [](const Key& k) { return k.xl; },
      [](const Key& a, const Key& c) { return a.xl < c.xl || (a.xl == c.xl && a.face < c.face); });
  std::vector<Interval>& sorted = scratch.sorted;
  sorted.clear();
  for (const Key& k : keys) sorted.push_back(ivs[k.index]);
  ivs.swap(sorted);
  // The events: every interval's ends and the line's, sorted, once each.
  // The left ends are in order already: only the right ends are sorted,
  // then the two merged.
  std::vector<double>& ends = scratch.ends;
  ends.assign({0.0, width});
  for (const Interval& iv : ivs) ends.push_back(iv.xr);
  column_sort(
      ends, scratch.events_tmp, scratch.count, scratch.cols, cam.width, [](double x) { return x; },
      [](double a, double c) { return a < c; });
  std::vector<double>& events = scratch.events;
  events.resize(ivs.size() + ends.size());
  {
    size_t a = 0, b = 0, k = 0;
    while (a < ivs.size() && b < ends.size())
      events[k++] = ivs[a].xl < ends[b] ? ivs[a++].xl : ends[b++];
    for (; a < ivs.size(); ++a) events[k++] = ivs[a].xl;
    for (; b < ends.size(); ++b) events[k++] = ends[b];
  }
  events.erase(std::unique(events.begin(), events.end()), events.end());

  auto emit = [&](double x0, double x1, int face) {
    if (!(x1 > x0)) return;
    if (!out.empty() && out.back().face == face && out.back().x1 == x0) {
      out.back().x1 = x1;
    } else {
      out.push_back(VisibleSegment{x0, x1, face});
    }
  };
  // Is a nearer than c at x, where their inverse depths are ga and gc?
  // Larger 1/s is nearer; within kTieRel the surfaces coincide and the tie
  // rule decides.
  auto nearer = [&](const Interval& a, double ga, const Interval& c, double gc) {
    if (!(gc > 0)) return ga > 0;
    if (!(ga > 0)) return false;
    if (ga > gc * (1.0 + kTieRel)) return true;
    if (gc > ga * (1.0 + kTieRel)) return false;
    return wins_tie(scan, a.face, c.face);
  };
  std::vector<const Interval*>& active = scratch.active;
  active.clear();
  size_t next = 0;
  using Range = VisibleScratch::Range;
  std::vector<Range>& stack = scratch.stack;
  for (size_t e = 0; e + 1 < events.size(); ++e) {
    const double lo = events[e], hi = events[e + 1];
    while (next < ivs.size() && ivs[next].xl <= lo) active.push_back(&ivs[next++]);
    std::erase_if(active, [&](const Interval* iv) { return iv->xr <= lo; });
    if (active.empty()) {
      emit(lo, hi, -1);
      continue;
    }
    stack.assign(1, Range{lo, hi});
    int splits = 0;
    while (!stack.empty()) {
      const Range r = stack.back();
      stack.pop_back();
      const double mid = 0.5 * (r.lo + r.hi);
      const Interval* top = nullptr;
      double top_mid = 0;
      for (const Interval* iv : active) {
        const double g = iv->d.at(mid);
        if (g > 0 && (!top || nearer(*iv, g, *top, top_mid))) {
          top = iv;
          top_mid = g;
        }
      }
      if (!top) {
        emit(r.lo, r.hi, -1);
        continue;
      }
      // A face nearer than the top at either end crosses it inside: split
      // there (its depth line meets the top's).
      double split = -1;
      if (splits < 64) {
        const double top_lo = top->d.at(r.lo), top_hi = top->d.at(r.hi);
        for (const Interval* iv : active) {
          if (iv == top || !(nearer(*iv, iv->d.at(r.lo), *top, top_lo) ||
                             nearer(*iv, iv->d.at(r.hi), *top, top_hi)))
            continue;
          const double den = iv->d.g1 - top->d.g1;
          if (den == 0) continue;
          const double x = (top->d.g0 - iv->d.g0) / den;
          if (x > r.lo && x < r.hi) {
            split = x;
            break;
          }
        }
      }
      if (split < 0) {
        emit(r.lo, r.hi, top->face);
        continue;
      }
      ++splits;
      stack.push_back(Range{split, r.hi});  // popped second: x order kept
      stack.push_back(Range{r.lo, split});
    }
  }
}

}  // namespace locus
