// The scanline pass of the local method (paper §3.1, §3.2; METHOD.md §4):
// every face (polygons, polyhedron faces, mesh triangles, and the faces of
// curved bodies' bounding polyhedra) is projected once; per scanline the
// faces crossing it give x-intervals, and the visible face at each sample is
// the nearest of the intervals covering it.
#pragma once

#include <optional>
#include <vector>

#include "common/base/math.h"
#include "common/geometry/geometry.h"
#include "common/prepare/scan_scene.h"

namespace locus {

class PreparedScene;
struct CameraFrame;

// One face's depth along a sample line: 1/s = g0 + g1 x, with s the eye-ray
// parameter along the unnormalised direction w + a u + b v and x the image
// x (pixels). Planar faces make it linear in x, so depth order changes only
// where two such lines cross.
struct LineDepth {
  double g0 = 0, g1 = 0;
  double at(double x) const { return g0 + g1 * x; }
};
// In two steps: what does not depend on the line (the face's normal
// against the camera's axes, its plane's offset from the eye; visible_faces
// uses it too), then the line's.
struct FaceDepth {
  double nw, nv, nu, num;
};
FaceDepth face_depth(const ScanFace& f, const CameraFrame& cam, const Vec3& eye);
LineDepth line_depth(const FaceDepth& p, const CameraFrame& cam, double b);

// Does face fi hide face fj where their depths are within rounding of each
// other (coincident surfaces)? A bounding polyhedron first (its pixels are
// traced, and the trace finds the truth), then the first-defined surface.
bool wins_tie(const ScanScene& scan, int fi, int fj);

// The x where face f's outline crosses the sample line y, sorted: pairs
// [xs[2k], xs[2k+1]) are inside. Each edge is taken from its upper to its
// lower end (half-open in y), so an edge shared by two faces gives the same
// x in both: no cracks, no double coverage.
void outline_crossings(const ScanFace& f, double y, std::vector<double>& xs);

// A visible interval of one face on a sample line (face -1: background).
struct VisibleSegment {
  double x0, x1;
  int face;
};

// One face's x-interval on a sample line, with its depth along it.
struct DepthInterval {
  double xl, xr;
  int face;
  LineDepth d;
};

// Buffers of visible_segments(), kept between calls. After a call, `ivs`
// holds the intervals of every face crossing the line, sorted by xl. The
// faces' y extents and depth parts are kept for the list last passed,
// known by its address and its scene's: a list, scene or camera changed in
// place between two calls with one scratch would be read stale (the scan
// scene's lists and camera are fixed for a frame; a scratch lives for one
// band).
struct VisibleScratch {
  struct Range {
    double lo, hi;
  };
  struct Key {
    double xl;
    int face, index;
  };
  std::vector<DepthInterval> ivs, sorted;
  std::vector<Key> keys, keys_tmp;
  std::vector<double> xs, ends, events, events_tmp;
  // The faces of the list `y_of` of `y_scene`, in its order: their y
  // extents and the line-independent part of their depth (face_depth).
  struct RowFace {
    double ymin, ymax;
    FaceDepth depth;
  };
  const std::vector<int>* y_of = nullptr;
  const ScanScene* y_scene = nullptr;
  std::vector<RowFace> row_faces;
  std::vector<int> count, cols;
  std::vector<const DepthInterval*> active;
  std::vector<Range> stack;
};

// The visible segments of the sample line at image y (a sub-scanline of
// multi-scanning), covering [0, width), among `faces` (paper §3.1: hidden
// surfaces per scanline). Faces are resolved by depth, and a segment is
// split where two faces' depth order changes (interpenetration): their
// inverse depths are linear in x.
void visible_segments(const ScanScene& scan, const CameraFrame& cam, double y,
                      const std::vector<int>& faces, VisibleScratch& scratch,
                      std::vector<VisibleSegment>& out);

// The visible face's own hit along a sample ray (paper §3.2: a ray-plane
// intersection, no search), or nullopt when the sample grazes the face's
// edge or the face lies inside hither's sphere there (see on_face): the
// caller then traces the ray.
std::optional<Crossing> hit_on_face(const PreparedScene& ps, const ScanFace& f, const Ray& ray);

// The point of face f's plane along origin + t dir (paper §3.2: a
// ray-plane intersection); not finite where dir is parallel to the plane.
Vec3 face_point(const ScanFace& f, const Vec3& origin, const Vec3& dir);

// Is the hit at ray parameter t on face f's plane? A convex body's face
// seen inside hither's sphere is not where the body's nearest crossing
// beyond hither lies (that is another of its faces): such a sample needs a
// ray of its own, and the face's shadows do not hold for it.
bool on_face(const ScanFace& f, const Vec3& origin, const Vec3& dir, double t);


// The visible face (index into ScanScene::faces, or -1 for background) at
// each pixel centre of row j, with the eye-ray distance parameter s along
// the unnormalised direction (w + a u + b v).
struct RowVisibility {
  std::vector<int> face;
  std::vector<double> s;
  int spans = 0;  // maximal runs of pixels with the same visible face
};

RowVisibility visible_faces(const ScanScene& scan, const CameraFrame& cam, const Vec3& eye, int row);

}  // namespace locus
