// The faces the scanline pass scans (paper §3.1; METHOD.md §4): every
// polygon, polyhedron face, mesh triangle, and face of a curved body's
// bounding polyhedron, projected once per frame and bucketed by the rows it
// crosses. Built here, with the rest of the frame's preparation; scanned by
// common/scan/scanline.h.
#pragma once

#include <vector>

#include "common/base/math.h"

namespace locus {

class PreparedScene;
struct CameraFrame;

// A face as the scanline pass sees it: its plane (world space) for depth,
// and its outline projected to image coordinates (x right, y down, pixels).
struct ScanFace {
  Vec3 normal;  // plane: dot(normal, p) = offset
  double offset = 0;
  int prim = -1;        // index into PrimitiveSet::prims (the surface it belongs to)
  // Its object's material, and whether its primitive has vertex normals
  // (has_vertex_normals): read for every span, kept here so that the
  // scanline does not reach for the primitive and its object, which lie far
  // apart in memory where faces are many.
  int material = 0;
  bool smooth = false;
  bool curved = false;  // a face of a curved body's bounding polyhedron
  // Part of the face lies within hither's sphere, so it is cut by a curved
  // edge no scanline computation sees: its pixels are traced like a curved
  // body's.
  bool near_hither = false;
  std::vector<Vec2> outline;  // projected, after clipping at the near plane
  double ymin = 0, ymax = 0;
};

// Faces of a scene, bucketed by the rows whose sample lines they cross. Built
// once per frame; rows are then independent of each other, so a band that
// starts at any row computes exactly what an unbanded render does.
struct ScanScene {
  std::vector<ScanFace> faces;
  std::vector<std::vector<int>> rows;  // rows[j]: faces crossing y = j + 0.5
  // Multi-scanning only: cover[j]: faces meeting some y in [j, j + 1].
  std::vector<std::vector<int>> cover;
  // A curved body's bounding polyhedron contains the eye or is cut by the
  // near plane: its span is the whole screen, every pixel is traced.
  bool trace_everything = false;
  // Some face reaches into hither's sphere (ScanFace::near_hither).
  bool any_near_hither = false;
};

// The depth of the near plane the faces are clipped at: far in front of
// hither's sphere, so nothing visible is lost (pixels whose surface lies
// within hither are traced instead, see local_rows).
double scan_near_depth(const CameraFrame& cam, double eps);

// A curved body's bounding polyhedron whose image is at most this many
// pixels across (its projected vertices' extent in x and in y) enters the
// scan scene as one face instead of its front faces: the convex hull of its
// projected vertices, which is the outline their union covers, on the
// plane facing the eye through its nearest vertex, so that it lies in front
// of the body as they do (docs/renderer.md, "Small curved bodies"). An
// icosahedron's ten front faces over a body a few pixels wide are finer
// than the pixels, and at SPD balls level 6 (597,871 spheres at 512²) they
// were 2.1 GB and most of the frame's time.
inline constexpr double kSilhouettePixels = 8.0;

// On up to `threads` threads (parallel_for, common/base/parallel.h):
// the primitives' faces by chunks, joined in primitive order, so the scan
// scene is the same, bit for bit, for any count. The faces closed solids
// turn away from the eye are left out (PreparedScene::culls, and the
// polyhedra's own; hidden_faces.h). `silhouette_pixels`: kSilhouettePixels
// (0: every bounding polyhedron by its faces, for tests).
ScanScene build_scan_scene(const PreparedScene& ps, bool multiscan, int threads = 1,
                           double silhouette_pixels = kSilhouettePixels);

// No faces, every pixel traced (Visibility::kRays): the rows' passes find
// an eye ray per sample, as inside a curved body's span.
ScanScene traced_scan_scene(int height, bool multiscan);

}  // namespace locus
