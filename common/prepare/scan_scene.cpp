#include "common/prepare/scan_scene.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "common/base/parallel.h"
#include "common/prepare/bounding.h"
#include "common/prepare/hidden_faces.h"
#include "common/prepare/prepared.h"

namespace locus {
namespace {

struct Projector {
  const CameraFrame& cam;
  double z_near;

  double depth(const Vec3& p) const { return glm::dot(p - cam.from, cam.w); }
  // Image coordinates of a point in front of the eye (SHADING.md camera,
  // inverted): x right, y down, in pixels.
  Vec2 project(const Vec3& p) const { return cam.project(p); }
};

// Sutherland-Hodgman against the near plane depth >= z_near, into `out`.
// Sets *clipped when any part of the outline lay behind it.
void clip_near(const std::vector<Vec3>& poly, const Projector& pr, bool* clipped,
               std::vector<Vec3>& out) {
  out.clear();
  const size_t n = poly.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec3& a = poly[i];
    const Vec3& b = poly[(i + 1) % n];
    const double da = pr.depth(a) - pr.z_near, db = pr.depth(b) - pr.z_near;
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) {
      out.push_back(a + (da / (da - db)) * (b - a));
    }
    if (da < 0) *clipped = true;
  }
}

// One face into the scan scene: clipped at the near plane, projected, its
// rows' extent and whether it reaches into hither's sphere.
struct FaceAdder {
  const PreparedScene& ps;
  const CameraFrame& cam;
  const Projector& pr;
  ScanScene& scan;
  double silhouette_pixels;       // build_scan_scene's
  std::vector<Vec3> kept;         // the clipped outline, reused from face to face
  std::vector<Vec3> pts;          // a bounding face's outline, reused
  std::vector<Vec2> image;        // a small polyhedron's projected vertices

  void add(const std::vector<Vec3>& outline, const Vec3& normal, double offset, int prim,
           bool curved, bool back = false) {
    bool clipped = false;
    if (back) {
      // Only whether the near plane cuts it (clip_near's *clipped).
      for (const Vec3& p : outline) clipped = clipped || pr.depth(p) - pr.z_near < 0;
      if (curved && clipped) scan.trace_everything = true;
      return;
    }
    clip_near(outline, pr, &clipped, kept);
    if (curved && clipped) scan.trace_everything = true;
    if (kept.size() < 3) return;
    ScanFace f;
    f.normal = normal;
    f.offset = offset;
    f.prim = prim;
    const PrimRef& ref = ps.prims.prims[prim];
    f.material = ps.object_material[ref.object];
    f.smooth = has_vertex_normals(ps.prims, ref);
    f.curved = curved;
    if (!curved && cam.hither > 0) f.near_hither = reaches_hither(kept, normal, offset);
    f.ymin = 1e300;
    f.ymax = -1e300;
    f.outline.reserve(kept.size());
    for (const Vec3& p : kept) {
      f.outline.push_back(pr.project(p));
      f.ymin = std::min(f.ymin, f.outline.back().y);
      f.ymax = std::max(f.ymax, f.outline.back().y);
    }
    if (!(f.ymax > f.ymin)) return;  // edge-on in y: crosses no sample line
    scan.faces.push_back(std::move(f));
  }

  // Conservative: the plane passes within hither of the eye and the face's
  // bounding sphere reaches into hither's sphere.
  bool reaches_hither(const std::vector<Vec3>& kept, const Vec3& normal, double offset) const {
    Vec3 c(0.0);
    for (const Vec3& p : kept) c += p;
    c /= static_cast<double>(kept.size());
    double r = 0;
    for (const Vec3& p : kept) r = std::max(r, glm::length(p - c));
    return std::abs(glm::dot(normal, cam.from) - offset) < cam.hither &&
           glm::length(c - cam.from) - r < cam.hither;
  }

  // A curved body's (or CSG object's) bounding polyhedra (paper §3.1,
  // Fig. 3): their front faces, and the back faces only as far as the near
  // plane goes.
  void add_bounding_faces(const Scene& scene, int object, int prim) {
    for (const Polyhedron& poly : bounding_polyhedra(scene, object)) {
      if (add_silhouette(poly, prim)) continue;
      // The eye inside the polyhedron: the body may be anywhere along
      // every eye ray.
      bool eye_inside = true;
      for (const auto& face : poly.faces) {
        pts.clear();
        for (int v : face) pts.push_back(poly.vertices[v]);
        const Vec3 n = newell_normal(pts);
        const bool front = glm::dot(n, cam.from - pts[0]) > 0;
        if (front) eye_inside = false;
        // A face turned away from the eye lies behind the polyhedron's
        // front faces, whose outlines cover the body's: it is only
        // checked against the near plane.
        add(pts, n, glm::dot(n, pts[0]), prim, true, !front);
      }
      if (eye_inside) scan.trace_everything = true;
    }
  }

  // A bounding polyhedron whose image is at most silhouette_pixels across,
  // wholly in front of the near plane, as one face (kSilhouettePixels): the
  // hull of its projected vertices, which is the union of its front faces'
  // outlines (a convex polyhedron's image is its vertices' hull), on the
  // plane facing the eye through its nearest vertex. Its span is sampled
  // as theirs was (SubLineBuilder::curved); only a surface lying between
  // that plane and the polyhedron's front faces is now traced there
  // instead of scan-converted. Returns false where the faces are added.
  bool add_silhouette(const Polyhedron& poly, int prim) {
    if (!(silhouette_pixels > 0) || poly.vertices.empty()) return false;
    double nearest = kInf;
    Vec2 lo(kInf), hi(-kInf);
    image.clear();
    for (const Vec3& v : poly.vertices) {
      const double z = pr.depth(v);
      if (!(z >= pr.z_near)) return false;  // the near plane cuts it, or the eye is inside
      nearest = std::min(nearest, z);
      image.push_back(pr.project(v));
      lo = glm::min(lo, image.back());
      hi = glm::max(hi, image.back());
    }
    if (!(std::max(hi.x - lo.x, hi.y - lo.y) <= silhouette_pixels)) return false;
    const std::vector<int> hull = convex_hull_2d(image);
    if (hull.size() < 3) return false;
    // The hull's corners on that plane, along their eye rays.
    pts.clear();
    for (const int i : hull) {
      const Vec3 d = cam.direction(image[i].x, image[i].y);
      pts.push_back(cam.from + (nearest / glm::dot(d, cam.w)) * d);
    }
    const Vec3 n = -cam.w;  // towards the eye
    add(pts, n, glm::dot(n, pts[0]), prim, true);
    return true;
  }
};

// scan.rows[j]: the faces whose y extent holds the sample line y = j + 0.5;
// with multi-scanning also scan.cover[j]: those meeting some y in [j, j + 1]
// (one row of margin each way).
void bucket_rows(ScanScene& scan, int height, bool multiscan) {
  scan.rows.assign(height, {});
  for (int f = 0; f < static_cast<int>(scan.faces.size()); ++f) {
    const ScanFace& face = scan.faces[f];
    const int j0 = clamped_ceil(face.ymin - 0.5, 0, height);
    const int j1 = clamped_ceil(face.ymax - 0.5, 0, height);
    for (int j = j0; j < j1; ++j) scan.rows[j].push_back(f);
  }
  if (!multiscan) return;
  scan.cover.assign(height, {});
  for (int f = 0; f < static_cast<int>(scan.faces.size()); ++f) {
    const ScanFace& face = scan.faces[f];
    const int j0 = clamped_floor(face.ymin, 1, height + 1) - 1;
    const int j1 = clamped_ceil(face.ymax, -1, height - 1) + 1;
    for (int j = j0; j < j1; ++j) scan.cover[j].push_back(f);
  }
}

}  // namespace

double scan_near_depth(const CameraFrame& cam, double eps) {
  return std::max(1e-12, 1e-6 * std::max(cam.hither, eps));
}

ScanScene build_scan_scene(const PreparedScene& ps, bool multiscan, int threads,
                           double silhouette_pixels) {
  const CameraFrame& cam = ps.camera;
  const double z_near = scan_near_depth(cam, ps.eps);
  const Projector pr{cam, z_near};
  const PrimitiveSet& set = ps.prims;
  const int n = static_cast<int>(set.prims.size());
  // The primitives' faces by chunks, each chunk's into its own part, the
  // parts joined in order: the faces in primitive order, as one pass makes
  // them, for any number of threads.
  constexpr int kGrain = 256;
  const int chunks = chunk_count(n, kGrain, 4 * std::max(1, threads));
  std::vector<ScanScene> parts(chunks);
  parallel_for(chunks, threads, [&](int c) {
    FaceAdder faces{ps, cam, pr, parts[c], silhouette_pixels, {}, {}, {}};
    const int end = chunk_edge(n, c + 1, chunks);
    // Bounding polyhedra are per object; a CSG or quadric object is one prim.
    for (int i = chunk_edge(n, c, chunks); i < end; ++i) {
      const PrimRef& ref = set.prims[i];
      switch (ref.kind) {
        case PrimKind::kPolygon: {
          // Back faces of closed solids are never the nearest (hidden_faces.h).
          if (ps.culls[i] & kCullEye) break;
          const PolygonPrim& p = set.polygons[ref.index];
          faces.add(polygon_outline(p), p.normal, p.offset, i, false);
          break;
        }
        case PrimKind::kTriangle: {
          const TrianglePrim& t = set.triangles[ref.index];
          faces.add({t.p0, t.p0 + t.e1, t.p0 + t.e2}, t.normal, glm::dot(t.normal, t.p0), i, false);
          break;
        }
        case PrimKind::kConvex: {
          const ConvexPrim& cv = set.convexes[ref.index];
          const bool hides = convex_hides_back_faces(cv, cam, z_near);
          for (size_t k = 0; k < cv.faces.size(); ++k) {
            if (hides && faces_away(cv.normals[k], cv.offsets[k], cam.from)) continue;
            faces.add(cv.faces[k], cv.normals[k], cv.offsets[k], i, false);
          }
          break;
        }
        case PrimKind::kSphere:
        case PrimKind::kCone:
        case PrimKind::kCsg:
          faces.add_bounding_faces(ps.scene, ref.object, i);
          break;
      }
    }
  });
  ScanScene scan = std::move(parts[0]);
  for (int c = 1; c < chunks; ++c) {
    scan.faces.insert(scan.faces.end(), std::make_move_iterator(parts[c].faces.begin()),
                      std::make_move_iterator(parts[c].faces.end()));
    scan.trace_everything = scan.trace_everything || parts[c].trace_everything;
  }
  scan.any_near_hither = std::any_of(scan.faces.begin(), scan.faces.end(),
                                     [](const ScanFace& f) { return f.near_hither; });
  bucket_rows(scan, cam.height, multiscan);
  return scan;
}

ScanScene traced_scan_scene(int height, bool multiscan) {
  ScanScene scan;
  scan.trace_everything = true;
  bucket_rows(scan, height, multiscan);
  return scan;
}

}  // namespace locus
