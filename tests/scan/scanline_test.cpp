// visible_segments (the hidden-surface step of every sample line, paper
// §3.1) against a brute-force answer on hand-made faces: fronto-parallel
// rectangles at distinct depths, so the face seen at any point is the
// nearest rectangle holding it. With many faces in one pixel column the
// line's intervals and events take column_sort's std::sort path there;
// with few, its insertion path only: both must give the same, right,
// segments.
#include "common/scan/scanline.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/prepare/scan_scene.h"

namespace locus {
namespace {

struct Rect {
  double x0, x1, y0, y1, depth;  // image coordinates; depth along -w
};

// A face in the plane w . p = -depth in front of the eye at the origin
// (looking down -z), its outline the rectangle in image coordinates.
ScanFace face_of(const Rect& r) {
  ScanFace f;
  f.normal = Vec3(0, 0, 1);
  f.offset = -r.depth;
  f.prim = 0;
  f.outline = {Vec2(r.x0, r.y0), Vec2(r.x1, r.y0), Vec2(r.x1, r.y1), Vec2(r.x0, r.y1)};
  f.ymin = r.y0;
  f.ymax = r.y1;
  return f;
}

// Checks the segments of the line y: in order, contiguous over [0, width),
// and each one's face the nearest rectangle holding its middle (-1: none).
void check_line(const std::vector<Rect>& rects, double y) {
  Camera c;
  c.from = Vec3(0, 0, 0);
  c.at = Vec3(0, 0, -1);
  c.width = c.height = 64;
  const CameraFrame cam(c);
  ScanScene scan;
  std::vector<int> faces;
  for (const Rect& r : rects) {
    faces.push_back(static_cast<int>(scan.faces.size()));
    scan.faces.push_back(face_of(r));
    scan.faces.back().prim = faces.back();
  }
  VisibleScratch scratch;
  std::vector<VisibleSegment> segs;
  visible_segments(scan, cam, y, faces, scratch, segs);
  ASSERT_FALSE(segs.empty());
  EXPECT_EQ(segs.front().x0, 0.0);
  EXPECT_EQ(segs.back().x1, 64.0);
  for (size_t k = 0; k < segs.size(); ++k) {
    ASSERT_LT(segs[k].x0, segs[k].x1) << "segment " << k;
    if (k > 0) {
      ASSERT_EQ(segs[k].x0, segs[k - 1].x1) << "segment " << k;
    }
    const double x = 0.5 * (segs[k].x0 + segs[k].x1);
    int want = -1;
    for (size_t i = 0; i < rects.size(); ++i) {
      const Rect& r = rects[i];
      if (!(r.x0 <= x && x < r.x1 && r.y0 <= y && y < r.y1)) continue;
      if (want < 0 || r.depth < rects[want].depth) want = static_cast<int>(i);
    }
    EXPECT_EQ(segs[k].face, want) << "segment " << k << " [" << segs[k].x0 << ", " << segs[k].x1
                                  << ") at y " << y;
  }
}

std::vector<Rect> random_rects(int n, double x_lo, double x_hi, double max_w, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(x_lo, x_hi), uw(0.001, max_w), uy(0, 40);
  std::vector<Rect> rects;
  for (int i = 0; i < n; ++i) {
    const double x0 = ux(rng), y0 = uy(rng);
    // Distinct depths: no ties for the tie rule to settle.
    rects.push_back(Rect{x0, x0 + uw(rng), y0, y0 + 30, 2.0 + 0.01 * i + 0.001 * (i % 7)});
  }
  return rects;
}

TEST(VisibleSegments, FewFacesPerColumnAreResolvedByDepth) {
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const std::vector<Rect> rects = random_rects(40, 0, 60, 6, seed);
    for (const double y : {5.25, 20.5, 33.75}) check_line(rects, y);
  }
}

// Slivers crowded into pixel column 10 (hundreds of interval ends there,
// beyond column_sort's 32), among wider faces elsewhere on the line.
TEST(VisibleSegments, CrowdedColumnsAreResolvedByDepth) {
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    std::vector<Rect> rects = random_rects(200, 10.0, 10.99, 0.01, seed);
    const std::vector<Rect> wide = random_rects(30, 0, 60, 8, seed + 100);
    rects.insert(rects.end(), wide.begin(), wide.end());
    for (const double y : {5.25, 20.5, 33.75}) check_line(rects, y);
  }
}

}  // namespace
}  // namespace locus
