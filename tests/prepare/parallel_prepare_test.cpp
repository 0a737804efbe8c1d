// The frame's preparation on several threads (issue #27 item 4;
// common/base/parallel.h): the scan scene (paper §3.1) and the shadow
// volumes with their boxes (§4.1) built with 2, 3 and 8 threads are the
// ones one thread builds, field for field and bit for bit, and so are the
// images of configurations II-IV rendered on them. parallel_for runs every
// index once and hands a body's exception back to the caller.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/base/parallel.h"
#include "common/prepare/prepared.h"
#include "common/prepare/scan_scene.h"
#include "common/prepare/shadow_volume.h"
#include "common/render.h"
#include "common/scene/scene_io.h"

namespace locus {
namespace {

// Scenes with more than two chunks of primitives (256 each) and several
// lights: s2 gears (concave polygons, 1,169 primitives), s2 sombrero
// (7,938 triangles), s2 rings (long cylinders cut into slices), def balls
// (7,382 spheres over a floor, 3 lights), and the paper's scene (d).
const char* const kScenes[] = {"spd/s2/gears.nff", "spd/s2/sombrero.nff", "spd/s2/rings.nff",
                               "spd/def/balls.nff", "paper:d_spheres_2lights.json"};

Scene load(const std::string& name, int width, int height) {
  const std::string path = name.rfind("paper:", 0) == 0
                               ? std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/" + name.substr(6)
                               : std::string(LOCUS_SHARED_DIR) + "/" + name;
  auto scene = load_scene(path);
  EXPECT_TRUE(scene.ok()) << path << ": " << scene.status().message();
  if (!scene.ok()) return Scene{};
  scene->camera.width = width;
  scene->camera.height = height;
  return *scene;
}

std::shared_ptr<const PreparedScene> prepare(const Scene& scene, RenderParams p, int threads) {
  p.threads = threads;
  auto ps = prepare_scene(scene, p);
  EXPECT_TRUE(ps.ok()) << ps.status().message();
  return ps.ok() ? *ps : nullptr;
}

bool same_bits(const void* a, const void* b, size_t n) { return std::memcmp(a, b, n) == 0; }

void expect_same_scan(const ScanScene& a, const ScanScene& b) {
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (size_t f = 0; f < a.faces.size(); ++f) {
    const ScanFace& x = a.faces[f];
    const ScanFace& y = b.faces[f];
    ASSERT_TRUE(same_bits(&x.normal, &y.normal, sizeof(Vec3)) &&
                same_bits(&x.offset, &y.offset, sizeof(double)) && x.prim == y.prim &&
                x.curved == y.curved && x.near_hither == y.near_hither &&
                x.outline.size() == y.outline.size() &&
                same_bits(x.outline.data(), y.outline.data(), x.outline.size() * sizeof(Vec2)) &&
                same_bits(&x.ymin, &y.ymin, sizeof(double)) &&
                same_bits(&x.ymax, &y.ymax, sizeof(double)))
        << "face " << f;
  }
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.cover, b.cover);
  EXPECT_EQ(a.trace_everything, b.trace_everything);
  EXPECT_EQ(a.any_near_hither, b.any_near_hither);
}

void expect_same_volumes(const ShadowVolumes& a, const ShadowVolumes& b) {
  EXPECT_EQ(a.search, b.search);
  ASSERT_EQ(a.lights.size(), b.lights.size());
  for (size_t j = 0; j < a.lights.size(); ++j) {
    SCOPED_TRACE(testing::Message() << "light " << j);
    const LightVolumes& x = a.lights[j];
    const LightVolumes& y = b.lights[j];
    EXPECT_TRUE(same_bits(&x.position, &y.position, sizeof(Vec3)));
    EXPECT_TRUE(same_bits(&x.slack, &y.slack, sizeof(double)));
    ASSERT_EQ(x.set.planes.size(), y.set.planes.size());
    EXPECT_TRUE(same_bits(x.set.planes.data(), y.set.planes.data(),
                          x.set.planes.size() * sizeof(HalfSpace)));
    ASSERT_EQ(x.set.cam.size(), y.set.cam.size());
    EXPECT_TRUE(same_bits(x.set.cam.data(), y.set.cam.data(),
                          x.set.cam.size() * sizeof(VolumeSet::CameraDots)));
    ASSERT_EQ(x.set.volumes.size(), y.set.volumes.size());
    for (size_t v = 0; v < x.set.volumes.size(); ++v) {
      ASSERT_TRUE(x.set.volumes[v].kind == y.set.volumes[v].kind &&
                  x.set.volumes[v].first == y.set.volumes[v].first &&
                  x.set.volumes[v].count == y.set.volumes[v].count)
          << "volume " << v;
    }
    ASSERT_EQ(x.occluders.size(), y.occluders.size());
    for (size_t o = 0; o < x.occluders.size(); ++o) {
      ASSERT_TRUE(x.occluders[o].first == y.occluders[o].first &&
                  x.occluders[o].count == y.occluders[o].count &&
                  x.occluders[o].decides == y.occluders[o].decides &&
                  x.occluders[o].bound == y.occluders[o].bound)
          << "occluder " << o;
    }
    EXPECT_EQ(x.node_volume, y.node_volume);
  }
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t i = 0; i < a.parts.size(); ++i) {
    ASSERT_TRUE(a.parts[i].count == b.parts[i].count &&
                same_bits(&a.parts[i].base, &b.parts[i].base, sizeof(Vec3)) &&
                same_bits(&a.parts[i].scaled_axis, &b.parts[i].scaled_axis, sizeof(Vec3)))
        << "parts " << i;
  }
}

TEST(ParallelPrepare, SameScanSceneAndVolumesForAnyThreadCount) {
  for (const char* name : kScenes) {
    SCOPED_TRACE(name);
    const Scene scene = load(name, 96, 72);
    for (const Boxes boxes : {Boxes::kEyeShadow, Boxes::kNone}) {
      for (const int aa : {0, 4}) {
        RenderParams p;
        p.method = Method::kLocal;
        p.boxes = boxes;
        p.aa = aa;
        // The scan scene and volumes are what is compared: IV scans and
        // builds volumes even where a frame this small would be found or
        // shadowed by rays (sombrero: 100 occluders per row).
        if (boxes == Boxes::kEyeShadow) {
          p.visibility = Visibility::kScanline;
          p.shadows = ShadowPass::kVolumes;
        }
        const auto one = prepare(scene, p, 1);
        ASSERT_TRUE(one && one->scan && one->volumes);
        ASSERT_FALSE(one->volumes->lights.empty());
        for (const int threads : {2, 3, 8}) {
          SCOPED_TRACE(testing::Message() << "boxes " << static_cast<int>(boxes) << ", aa " << aa
                                          << ", threads " << threads);
          const auto many = prepare(scene, p, threads);
          ASSERT_TRUE(many && many->scan && many->volumes);
          expect_same_scan(*one->scan, *many->scan);
          expect_same_volumes(*one->volumes, *many->volumes);
        }
      }
    }
  }
}

bool bit_identical(const Image& a, const Image& b) {
  return a.width == b.width && a.height == b.height &&
         same_bits(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float));
}

// Whole frames, prepared and rendered on 1, 2 and 3 threads:
// configurations IV (point sampling and multi-scanning), III and II.
TEST(ParallelPrepare, SameImagesForAnyThreadCount) {
  for (const char* name : kScenes) {
    SCOPED_TRACE(name);
    const Scene scene = load(name, 48, 36);
    struct Config {
      Boxes boxes;
      int aa;
    };
    for (const Config c : {Config{Boxes::kEyeShadow, 0}, Config{Boxes::kEyeShadow, 2},
                           Config{Boxes::kEye, 0}, Config{Boxes::kNone, 0}}) {
      RenderParams p;
      p.method = Method::kLocal;
      p.boxes = c.boxes;
      p.aa = c.aa;
      p.threads = 1;
      auto one = render_image(scene, p);
      ASSERT_TRUE(one.ok()) << one.status().message();
      for (const int threads : {2, 3}) {
        p.threads = threads;
        auto many = render_image(scene, p);
        ASSERT_TRUE(many.ok()) << many.status().message();
        EXPECT_TRUE(bit_identical(one->pixels, many->pixels))
            << "boxes " << static_cast<int>(c.boxes) << ", aa " << c.aa << ", threads " << threads;
        EXPECT_EQ(one->stats.tests_shadow_volume, many->stats.tests_shadow_volume);
        EXPECT_EQ(one->stats.rays_shadow, many->stats.rays_shadow);
      }
    }
  }
}

TEST(ParallelFor, RunsEveryIndexOnceOnAnyThreadCount) {
  for (const int n : {0, 1, 2, 7, 100, 1000}) {
    for (const int threads : {1, 2, 3, 16}) {
      std::vector<std::atomic<int>> runs(n);
      for (auto& r : runs) r.store(0);
      parallel_for(n, threads, [&](int i) { runs[i].fetch_add(1); });
      for (int i = 0; i < n; ++i) ASSERT_EQ(1, runs[i].load()) << n << " " << threads << " " << i;
      std::vector<int> hit(n, 0);
      parallel_chunks(n, threads, 10, [&](int begin, int end) {
        ASSERT_LE(0, begin);
        ASSERT_LE(begin, end);
        ASSERT_LE(end, n);
        for (int i = begin; i < end; ++i) ++hit[i];
      });
      for (int i = 0; i < n; ++i) ASSERT_EQ(1, hit[i]) << n << " " << threads << " " << i;
    }
  }
}

TEST(ParallelFor, RethrowsABodysException) {
  for (const int threads : {1, 2, 4}) {
    EXPECT_THROW(parallel_for(50, threads,
                              [](int i) {
                                if (i == 17) throw std::runtime_error("seventeen");
                              }),
                 std::runtime_error);
  }
}

}  // namespace
}  // namespace locus
