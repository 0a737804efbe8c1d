// The scan scene's small curved bodies (common/prepare/scan_scene.h,
// kSilhouettePixels): one face each, covering what their bounding
// polyhedra's front faces covered, and the same image.
#include "common/prepare/scan_scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <utility>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/render.h"
#include "common/scan/scanline.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

using testing_util::camera_scene;
using testing_util::max_difference;
using testing_util::quad;

// A floor, one large sphere, and small spheres and cones (2-4 pixels
// across at 96 x 72) floating above the floor, some of them overlapping
// each other in the image.
Scene bodies_scene() {
  Scene s = camera_scene(Vec3(0.3, 2.5, 10), Vec3(0, 0, 0), 40, 96, 72);
  s.lights.push_back(Light{Vec3(-4, 6, 3), std::nullopt});
  Material mirror;
  mirror.color = Color(0.7);
  mirror.kd = 0.4;
  mirror.ks = 0.5;
  s.materials.push_back(mirror);  // 2
  s.objects.push_back(quad(Vec3(-9, -1, 9), Vec3(9, -1, 9), Vec3(9, -1, -9), Vec3(-9, -1, -9), 0));
  Object big;
  big.shape = Sphere{Vec3(-1.4, 0.6, -1), 1.2};
  big.material = 2;
  s.objects.push_back(big);
  for (int k = 0; k < 12; ++k) {
    const double x = -0.2 + 0.31 * (k % 6), y = 0.3 * (k / 6), z = 0.5 - 0.4 * (k % 3);
    Object o;
    if (k % 3 == 2) {
      o.shape = Cone{Vec3(x, y, z), 0.06, Vec3(x + 0.1, y + 0.15, z - 0.05), 0.03, true};
    } else {
      o.shape = Sphere{Vec3(x, y, z), 0.07 + 0.01 * (k % 4)};
    }
    o.material = k % 2 == 0 ? 2 : 1;
    s.objects.push_back(o);
  }
  return s;
}

RenderParams local_params(int aa) {
  RenderParams p;
  p.method = Method::kLocal;
  p.boxes = Boxes::kEyeShadow;
  p.aa = aa;
  return p;
}

std::map<int, int> faces_per_prim(const ScanScene& scan) {
  std::map<int, int> n;
  for (const ScanFace& f : scan.faces) ++n[f.prim];
  return n;
}

// The parts of [0, width) where a curved body's face is the visible one on
// sample line y, merged.
std::vector<std::pair<double, double>> curved_cover(const ScanScene& scan, const CameraFrame& cam,
                                                    double y, int row, VisibleScratch& scratch) {
  std::vector<VisibleSegment> segs;
  visible_segments(scan, cam, y, scan.cover[row], scratch, segs);
  std::vector<std::pair<double, double>> out;
  for (const VisibleSegment& s : segs) {
    if (s.face < 0 || !scan.faces[s.face].curved) continue;
    if (!out.empty() && out.back().second == s.x0) {
      out.back().second = s.x1;
    } else {
      out.emplace_back(s.x0, s.x1);
    }
  }
  return out;
}

TEST(ScanScene, ASmallCurvedBodyIsOneFaceCoveringWhatItsPolyhedronsFacesDid) {
  const Scene scene = bodies_scene();
  const RenderParams params = local_params(4);
  const PreparedScene ps(scene, params);
  ASSERT_TRUE(ps.scan);
  const ScanScene faces = build_scan_scene(ps, true, 1, 0.0);
  const ScanScene& outlines = *ps.scan;  // the default: kSilhouettePixels
  const std::map<int, int> by_faces = faces_per_prim(faces), by_outline = faces_per_prim(outlines);
  const int floor = 0, big = 1;
  EXPECT_EQ(by_outline.at(floor), 1);
  EXPECT_GT(by_faces.at(big), 3);
  EXPECT_EQ(by_outline.at(big), by_faces.at(big));  // 24 pixels across: its faces
  int small = 0;
  for (int prim = 2; prim < static_cast<int>(ps.prims.prims.size()); ++prim) {
    EXPECT_GE(by_faces.at(prim), 2) << prim;
    EXPECT_EQ(by_outline.at(prim), 1) << prim;
    ++small;
  }
  EXPECT_EQ(small, 12);
  EXPECT_LT(outlines.faces.size() + 30, faces.faces.size());

  // On every sub-scanline the curved bodies' spans are where they were, to
  // rounding.
  VisibleScratch a, b;
  int lines_with_bodies = 0;
  for (int row = 0; row < ps.camera.height; ++row) {
    for (int k = 0; k < 4; ++k) {
      const double y = row + 0.25 * k;
      const auto want = curved_cover(faces, ps.camera, y, row, a);
      const auto got = curved_cover(outlines, ps.camera, y, row, b);
      ASSERT_EQ(got.size(), want.size()) << "y " << y;
      for (size_t i = 0; i < got.size(); ++i) {
        EXPECT_NEAR(got[i].first, want[i].first, 1e-9) << "y " << y;
        EXPECT_NEAR(got[i].second, want[i].second, 1e-9) << "y " << y;
      }
      if (!want.empty()) ++lines_with_bodies;
    }
  }
  EXPECT_GT(lines_with_bodies, 60);
}

TEST(ScanScene, SmallCurvedBodiesAsOneFaceLeaveTheImageAsItWas) {
  const Scene scene = bodies_scene();
  for (int aa : {1, 4}) {
    const RenderParams params = local_params(aa);
    const PreparedScene outlines(scene, params);
    PreparedScene faces(scene, params);
    faces.scan = std::make_unique<ScanScene>(build_scan_scene(faces, true, 1, 0.0));
    const Band band{0, scene.camera.height};
    const BandResult x = render_band(outlines, band, params);
    const BandResult y = render_band(faces, band, params);
    EXPECT_EQ(max_difference(x.pixels, y.pixels), 0.0) << "aa " << aa;
    EXPECT_EQ(x.stats.pixels_ray_traced, y.stats.pixels_ray_traced) << "aa " << aa;
    EXPECT_GT(x.stats.pixels_ray_traced, 100) << "aa " << aa;
  }
}

TEST(ScanScene, ABodyTheNearPlaneCutsKeepsItsFaces) {
  // A small sphere around the eye: its polyhedron has vertices behind the
  // eye, so it is not one face, and every pixel is traced.
  Scene scene = camera_scene(Vec3(0, 0, 0), Vec3(0, 0, -1), 60, 32, 24);
  Object ball;
  ball.shape = Sphere{Vec3(0, 0, 0.01), 0.05};
  scene.objects.push_back(ball);
  const PreparedScene ps(scene, local_params(4));
  ASSERT_TRUE(ps.scan);
  EXPECT_TRUE(ps.scan->trace_everything);
}

TEST(ScanScene, EachFaceCarriesItsObjectsMaterialAndWhetherItsNormalVaries) {
  // The scanline reads a span's material and whether its shading normal
  // varies from the face (ScanFace::material, smooth), not from the
  // primitive's object: they must be that object's.
  Scene scene = bodies_scene();
  Material third;
  third.color = Color(0.2, 0.6, 0.3);
  third.kd = 0.8;
  scene.materials.push_back(third);  // 3
  Object patch;
  patch.shape = Patch{{Vec3(-3, -0.5, 2), Vec3(-1, -0.5, 2), Vec3(-1, 0.5, 1), Vec3(-3, 0.5, 1)},
                      {Vec3(0, 0.3, 1), Vec3(0.2, 0.3, 1), Vec3(0, 0.4, 1), Vec3(-0.2, 0.3, 1)}};
  patch.material = 3;
  scene.objects.push_back(patch);
  const PreparedScene ps(scene, local_params(4));
  ASSERT_TRUE(ps.scan);
  int smooth = 0, by_material[4] = {};
  for (const ScanFace& f : ps.scan->faces) {
    const PrimRef& ref = ps.prims.prims[f.prim];
    EXPECT_EQ(f.material, scene.objects[ref.object].material) << "face of prim " << f.prim;
    EXPECT_EQ(f.smooth, has_vertex_normals(ps.prims, ref)) << "face of prim " << f.prim;
    smooth += f.smooth;
    ++by_material[f.material];
  }
  EXPECT_EQ(smooth, 2);  // the patch's fan of two triangles
  for (int m = 0; m < 4; ++m) EXPECT_GT(by_material[m], 0) << "material " << m;
  for (int o = 0; o < static_cast<int>(scene.objects.size()); ++o)
    EXPECT_EQ(&ps.material_of(o), &ps.scene.materials[scene.objects[o].material]) << "object " << o;
}

}  // namespace
}  // namespace locus
