// The front/back relations of configuration IV (paper §4.1) as the frame
// makes them since issue #27: each receiver's list when a row first asks
// for it (receiver_candidates), from any thread; and the volumes of
// polyhedra built from their vertices listed once (docs/shadow-volumes.md,
// "Who can shadow whom"; bench/peers/README.md, "Prepare at scale").
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <thread>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/prepare/shadow_candidates.h"
#include "common/prepare/shadow_volume.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene_io.h"

namespace locus {
namespace {

std::shared_ptr<const PreparedScene> prepared(const std::string& spd) {
  auto scene = load_scene(std::string(LOCUS_SHARED_DIR) + "/spd/" + spd);
  EXPECT_TRUE(scene.ok()) << spd;
  scene->camera.width = 64;
  scene->camera.height = 48;
  RenderParams params;
  params.method = Method::kLocal;
  params.boxes = Boxes::kEyeShadow;
  params.shadows = ShadowPass::kVolumes;  // the lists are the volumes'
  auto ps = prepare_scene(*scene, params);
  EXPECT_TRUE(ps.ok()) << spd;
  return *ps;
}

void expect_same_direct(const std::vector<CandidateList::Direct>& a,
                        const std::vector<CandidateList::Direct>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].first, b[k].first);
    EXPECT_EQ(a[k].count, b[k].count);
    EXPECT_EQ(a[k].decides, b[k].decides);
  }
}

// Two preparations of one scene: one asked receiver by receiver in order
// on this thread, the other by two threads at once in opposite orders
// (each list made by whichever thread comes first, some by both). Every
// list is the same, so neither the order nor the thread that makes a list
// changes a row. s1 rings has long cylinders (lists per slice), gears
// concave polygons, balls spheres over a floor.
TEST(CandidateLists, SameListsWhateverTheOrderAndTheThread) {
  for (const char* spd : {"s1/balls.nff", "s1/rings.nff", "s1/gears.nff", "s2/tetra.nff"}) {
    SCOPED_TRACE(spd);
    const auto one = prepared(spd);
    const auto two = prepared(spd);
    ASSERT_TRUE(one->volumes && one->volumes->search);
    const int lights = static_cast<int>(one->volumes->lights.size());
    const int n = static_cast<int>(one->prims.prims.size());
    ASSERT_GT(lights, 0);
    ASSERT_GT(n, 0);
    for (int j = 0; j < lights; ++j) {
      for (int r = 0; r < n; ++r) receiver_candidates(*one, j, r);
    }
    std::thread up([&] {
      for (int j = 0; j < lights; ++j) {
        for (int r = 0; r < n; ++r) receiver_candidates(*two, j, r);
      }
    });
    for (int j = lights - 1; j >= 0; --j) {
      for (int r = n - 1; r >= 0; --r) receiver_candidates(*two, j, r);
    }
    up.join();
    size_t listed = 0;
    for (int j = 0; j < lights; ++j) {
      for (int r = 0; r < n; ++r) {
        const CandidateList& a = receiver_candidates(*one, j, r);
        const CandidateList& b = receiver_candidates(*two, j, r);
        EXPECT_EQ(&a, &receiver_candidates(*one, j, r));  // made once, kept
        ASSERT_EQ(a.ids, b.ids) << "light " << j << " receiver " << r;
        EXPECT_TRUE(std::is_sorted(a.ids.begin(), a.ids.end()));
        expect_same_direct(a.direct, b.direct);
        EXPECT_EQ(a.part_first, b.part_first);
        EXPECT_EQ(a.part_ids, b.part_ids);
        expect_same_direct(a.part_direct, b.part_direct);
        listed += a.ids.size();
      }
    }
    EXPECT_GT(listed, 0u);
  }
}

// add_polyhedron_volume with the polyhedron's vertices given once
// (`corners`, as the bounding polyhedra and the boxes give them) makes the
// volume it makes from the faces' repeated vertices: the same planes, bit
// for bit, in the same order. Random hulls of 4 to 40 points, lights
// around, beside, on a face's plane and inside.
TEST(ShadowVolume, VerticesListedOnceGiveTheSameVolume) {
  std::mt19937 rng(27);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int compared = 0;
  for (int t = 0; t < 300; ++t) {
    SCOPED_TRACE(testing::Message() << "case " << t);
    std::vector<Vec3> pts(4 + t % 37);
    for (Vec3& p : pts) p = Vec3(u(rng), u(rng), u(rng));
    const std::optional<Polyhedron> hull = make_hull(pts);
    if (!hull) continue;
    std::vector<std::vector<Vec3>> faces;
    std::vector<HalfSpace> planes;
    for (const auto& face : hull->faces) {
      std::vector<Vec3> f;
      for (int v : face) f.push_back(hull->vertices[v]);
      const Vec3 n = newell_normal(f);
      planes.push_back(HalfSpace{glm::normalize(n), glm::dot(glm::normalize(n), f[0])});
      faces.push_back(std::move(f));
    }
    Vec3 light = 4.0 * Vec3(u(rng), u(rng), u(rng));
    if (t % 10 == 0) light = 0.1 * light;                                      // inside, often
    if (t % 10 == 1) light = faces[0][0] + 3.0 * (faces[0][1] - faces[0][0]);  // in a face's plane
    for (const bool solid : {false, true}) {
      VolumeSet a, b;
      const int va = add_polyhedron_volume(a, faces, planes, light, solid);
      const int vb = add_polyhedron_volume(b, faces, planes, light, solid, &hull->vertices);
      ASSERT_EQ(va, vb);
      EXPECT_EQ(a.volumes[va].kind, b.volumes[vb].kind);
      ASSERT_EQ(a.planes.size(), b.planes.size());
      for (size_t i = 0; i < a.planes.size(); ++i) {
        EXPECT_EQ(a.planes[i].m, b.planes[i].m);
        EXPECT_EQ(a.planes[i].h, b.planes[i].h);
      }
      ++compared;
    }
  }
  EXPECT_GT(compared, 400);
}

}  // namespace
}  // namespace locus
