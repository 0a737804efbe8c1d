// The local method's visible-surface pass chosen per frame (issue #27;
// common/prepare/visibility.h): scanline where faces span pixels, eye rays
// where the scene is finer than its pixels; both give the same image. And
// configuration IV's shadows of scanned spans by rays instead of volumes
// (--shadows rays).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>

#include "common/base/image.h"
#include "common/farm/band_split.h"
#include "common/prepare/prepared.h"
#include "common/prepare/shadow_volume.h"
#include "common/prepare/visibility.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

// A square of n x n quads, each cut into two triangles, facing the camera
// over a floor, lit by one light; at size x size pixels; the quads reflect
// `ks`. n = 120 at 64 x 64: every triangle is smaller than a pixel (450
// boxes per row); n = 16: about 4 x 4 pixels each (24 per row: rays if
// most of them are traced in any case, the scanline if they are diffuse).
Scene grid_scene(int n, int size, double ks = 0.0) {
  std::ostringstream nff;
  nff << "v\nfrom 0 -3 0.2\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution " << size << ' '
      << size << "\nb 0.1 0.2 0.3\nl 2 -3 3\n";
  nff << "f 0.8 0.6 0.4 1 0 0 0 1\np 4\n-3 -3 -1\n3 -3 -1\n3 3 -1\n-3 3 -1\n";
  nff << "f 0.3 0.7 0.9 1 " << ks << " 0 0 1\n";
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double x0 = -1 + 2.0 * i / n, x1 = -1 + 2.0 * (i + 1) / n;
      const double z0 = -0.8 + 1.6 * j / n, z1 = -0.8 + 1.6 * (j + 1) / n;
      // A little relief, so that neighbouring faces are not coplanar.
      const double y = 0.05 * std::sin(7.0 * x0 + 5.0 * z0);
      nff << "p 3\n" << x0 << ' ' << y << ' ' << z0 << '\n' << x1 << ' ' << y << ' ' << z0 << '\n'
          << x1 << ' ' << y << ' ' << z1 << '\n';
      nff << "p 3\n" << x0 << ' ' << y << ' ' << z0 << '\n' << x1 << ' ' << y << ' ' << z1 << '\n'
          << x0 << ' ' << y << ' ' << z1 << '\n';
    }
  }
  auto scene = parse_nff(nff.str(), "grid.nff");
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  return scene.ok() ? *scene : Scene{};
}

RenderParams iv(int aa, Visibility v = Visibility::kAuto,
               ShadowPass shadows = ShadowPass::kAuto) {
  RenderParams p;
  p.method = Method::kLocal;
  p.boxes = Boxes::kEyeShadow;
  p.aa = aa;
  p.threads = 2;
  p.visibility = v;
  p.shadows = shadows;
  return p;
}

RenderParams iv(int aa, ShadowPass shadows) { return iv(aa, Visibility::kAuto, shadows); }

// RMS and largest difference over every channel of two images of one size.
std::pair<double, double> difference(const Image& a, const Image& b) {
  double sum = 0, worst = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = a.pixel(x, y)[c] - b.pixel(x, y)[c];
        sum += d * d;
        worst = std::max(worst, std::abs(d));
      }
    }
  }
  return {std::sqrt(sum / (3.0 * a.width * a.height)), worst};
}

TEST(Visibility, APointSampledFrameFinerThanItsPixelsIsRayCastAndBuildsNoFacesOrVolumes) {
  // Multi-scanned, it scans (the exact coverage is the method's point);
  // its 28,800 occluders, 450 per row, are shadowed by rays (ShadowPass).
  auto multi = prepare_scene(grid_scene(120, 64), iv(4));
  ASSERT_TRUE(multi.ok());
  EXPECT_FALSE((*multi)->by_rays);
  EXPECT_FALSE((*multi)->volumes);
  auto with_volumes = prepare_scene(grid_scene(120, 64), iv(4, ShadowPass::kVolumes));
  ASSERT_TRUE(with_volumes.ok());
  EXPECT_TRUE((*with_volumes)->volumes) << "forced, the volumes are built";
  // Forced, a multi-scanned frame is ray cast too.
  for (int aa : {0, 4}) {
    auto ps = prepare_scene(grid_scene(120, 64), iv(aa, aa == 0 ? Visibility::kAuto : Visibility::kRays));
    ASSERT_TRUE(ps.ok()) << ps.status().message();
    EXPECT_TRUE((*ps)->by_rays) << "aa " << aa;
    ASSERT_TRUE((*ps)->scan);
    EXPECT_TRUE((*ps)->scan->faces.empty());
    EXPECT_TRUE((*ps)->scan->trace_everything);
    EXPECT_FALSE((*ps)->volumes) << "rays find the shadows: no volumes are built";
    const BandResult r = render_band(**ps, Band{0, 64}, iv(aa));
    EXPECT_EQ(r.stats.visibility, "rays");
    EXPECT_EQ(r.stats.shadow_method, "rays");
    EXPECT_EQ(r.stats.tests_shadow_volume, 0u);
    EXPECT_GT(r.stats.rays_shadow, 0u);
  }
}

TEST(Visibility, ThePapersSceneIsScanned) {
  auto scene = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_1light.json");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  for (int aa : {0, 4}) {
    auto ps = prepare_scene(*scene, iv(aa));
    ASSERT_TRUE(ps.ok());
    EXPECT_FALSE((*ps)->by_rays) << "aa " << aa;
    EXPECT_FALSE((*ps)->scan->faces.empty());
    ASSERT_TRUE((*ps)->volumes);
    Scene small = *scene;
    small.camera.width = small.camera.height = 32;
    auto r = render_image(small, iv(aa));
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->stats.visibility, "scanline");
    // The spans' shadows by volumes; auto's points by rays
    // (PreparedScene::point_shadows_by_rays).
    EXPECT_EQ(r->stats.shadow_method, "volumes+rays");
  }
}

// Point sampled, rays; multi-scanned, the scanline's exact coverage. The
// farm's cost preview (point sampled, smaller) passes the way the frame
// will.
TEST(Visibility, TheChoiceFollowsTheSamplingAndThePreviewFollowsTheFrame) {
  const Scene scene = grid_scene(16, 64, 0.3);
  auto diffuse = prepare_scene(grid_scene(16, 64), iv(0));
  ASSERT_TRUE(diffuse.ok());
  EXPECT_FALSE((*diffuse)->by_rays) << "24 diffuse faces per row: the scanline is faster";
  auto point = prepare_scene(scene, iv(0));
  auto multi = prepare_scene(scene, iv(4));
  ASSERT_TRUE(point.ok() && multi.ok());
  EXPECT_TRUE((*point)->by_rays);
  EXPECT_FALSE((*multi)->by_rays);
  EXPECT_EQ(frame_passes(scene, iv(4)).visibility, Visibility::kScanline);
  EXPECT_EQ(frame_passes(scene, iv(0)).visibility, Visibility::kRays);
  EXPECT_EQ(frame_passes(scene, iv(4, Visibility::kRays)).visibility, Visibility::kRays);
  RenderParams ii = iv(4);
  ii.boxes = Boxes::kNone;
  EXPECT_EQ(frame_passes(scene, ii).visibility, Visibility::kAuto) << "II and III always scan";
  EXPECT_EQ(frame_passes(scene, ii).shadows, ShadowPass::kAuto) << "and build volumes";
  auto ps = prepare_scene(scene, ii);
  ASSERT_TRUE(ps.ok());
  EXPECT_FALSE((*ps)->by_rays);
  // The preview's prediction: rows of a scanned frame cost span and volume
  // work, which a ray-cast preview would not count.
  auto costs = predict_row_costs(scene, iv(4), 1);
  ASSERT_TRUE(costs.ok()) << costs.status().message();
  EXPECT_EQ(costs->size(), 64u);
}

// Point sampled, both passes take the same samples (they differ only where
// a sample's centre grazes an edge). Multi-scanned, both approximate the
// pixels' integrals: each against a dense ray-traced reference, the
// scanline's exact coverage is the closer (why auto scans then), and rays'
// sampling with bisection (paper §3.3) stays near it.
TEST(Visibility, RaysAndScanlineRenderTheSamePicture) {
  auto d = load_scene(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_2lights.json");
  ASSERT_TRUE(d.ok());
  d->camera.width = 96;
  d->camera.height = 72;
  for (const Scene& scene : {*d, grid_scene(16, 64, 0.3)}) {
    RenderParams dense;
    dense.spp = 8;
    dense.threads = 2;
    auto ref = render_image(scene, dense);
    ASSERT_TRUE(ref.ok());
    for (int aa : {0, 4}) {
      auto scan = render_image(scene, iv(aa, Visibility::kScanline));
      auto rays = render_image(scene, iv(aa, Visibility::kRays));
      ASSERT_TRUE(scan.ok() && rays.ok());
      EXPECT_EQ(scan->stats.visibility, "scanline");
      EXPECT_EQ(rays->stats.visibility, "rays");
      const auto [rms, worst] = difference(scan->pixels, rays->pixels);
      const double scan_error = difference(scan->pixels, ref->pixels).first;
      const double rays_error = difference(rays->pixels, ref->pixels).first;
      SCOPED_TRACE("aa " + std::to_string(aa) + ", " + std::to_string(scene.camera.width) +
                   " wide: between the passes rms " + std::to_string(rms) + ", max " +
                   std::to_string(worst) + "; against the reference scanline " +
                   std::to_string(scan_error) + ", rays " + std::to_string(rays_error));
      if (aa == 0) {
        EXPECT_LT(rms, 2e-3);
        int differ = 0;
        for (int y = 0; y < scan->pixels.height; ++y)
          for (int x = 0; x < scan->pixels.width; ++x)
            for (int c = 0; c < 3; ++c)
              differ += std::abs(scan->pixels.pixel(x, y)[c] - rays->pixels.pixel(x, y)[c]) > 2.0 / 255;
        EXPECT_LE(differ, scan->pixels.width * scan->pixels.height / 100);
      } else {
        EXPECT_LE(scan_error, rays_error);
        EXPECT_LT(rays_error, 2.0 * scan_error + 0.01);
      }
    }
  }
}

TEST(Visibility, BandsOfAFrameFoundOrShadowedByRaysAreBitIdenticalToTheWhole) {
  for (int aa : {0, 4}) {
    testing_util::expect_bands_bit_identical(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_1light.json",
                                             iv(aa, Visibility::kRays));
    testing_util::expect_bands_bit_identical(LOCUS_SOURCE_DIR "/scenes/paper/c_thermometer.json",
                                             iv(aa, Visibility::kRays));
    testing_util::expect_bands_bit_identical(LOCUS_SOURCE_DIR "/scenes/paper/d_spheres_1light.json",
                                             iv(aa, ShadowPass::kRays));
  }
}

// Both choices of configuration IV (--visibility, --shadows) are refused
// elsewhere, the error naming the flag.
TEST(Visibility, AForcedPassIsForConfigurationIVOnly) {
  for (const RenderParams& forced :
       {iv(4, Visibility::kRays), iv(4, ShadowPass::kRays), iv(4, ShadowPass::kVolumes)}) {
    const bool vis = forced.visibility != Visibility::kAuto;
    const std::string flag =
        vis ? "--visibility rays"
            : "--shadows " + std::string(label_name(kShadowPassLabels, forced.shadows));
    RenderParams p = forced;
    EXPECT_TRUE(check_render_params(p).ok());
    p.boxes = Boxes::kEye;
    const Status s = check_render_params(p);
    EXPECT_FALSE(s.ok());
    EXPECT_NE(s.message().find(flag), std::string::npos) << s.message();
    EXPECT_NE(s.message().find("configuration IV"), std::string::npos) << s.message();
    p = forced;
    p.method = Method::kRaytrace;
    p.aa = 0;
    EXPECT_FALSE(check_render_params(p).ok());
    EXPECT_FALSE(prepare_scene(grid_scene(2, 16), p).ok()) << "prepare_scene checks it too";
  }
}

TEST(Visibility, StatsNameThePass) {
  Stats a;
  a.visibility = "scanline";
  EXPECT_NE(a.to_json().find("\"visibility\": {\"method\": \"scanline\"}"), std::string::npos)
      << a.to_json();
  Stats sum;
  sum += a;
  EXPECT_EQ(sum.visibility, "scanline") << "a sum of bands keeps the bands' pass";
}

// --shadows rays (docs/renderer.md "Shadows by rays"): no volumes are
// built, the shadows are the same t_pj (eqs. (2), (3)).
Scene paper_scene(const char* name, int w, int h) {
  auto scene = load_scene(std::string(LOCUS_SOURCE_DIR "/scenes/paper/") + name);
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  if (!scene.ok()) return Scene{};
  scene->camera.width = w;
  scene->camera.height = h;
  return *scene;
}

TEST(ShadowPass, RaysBuildNoVolumesAndCountNoVolumeTests) {
  const Scene scene = paper_scene("d_spheres_2lights.json", 48, 36);
  for (int aa : {0, 4}) {
    auto ps = prepare_scene(scene, iv(aa, ShadowPass::kRays));
    ASSERT_TRUE(ps.ok()) << ps.status().message();
    EXPECT_FALSE((*ps)->volumes);
    ASSERT_TRUE((*ps)->scan);
    EXPECT_FALSE((*ps)->scan->faces.empty()) << "visibility still scans";
    const BandResult r = render_band(**ps, Band{0, 36}, iv(aa, ShadowPass::kRays));
    EXPECT_EQ(r.stats.shadow_method, "rays");
    EXPECT_EQ(r.stats.visibility, "scanline");
    EXPECT_EQ(r.stats.tests_shadow_volume, 0u);
    EXPECT_GT(r.stats.rays_shadow, 0u);
  }
}

// Point sampled, the same t_pj at the same points: the images agree but
// where a sample grazes a shadow's edge. Multi-scanned, volumes give the
// shadows' edges on a span from their intervals and rays find them by
// bisection (sub_line.cpp figures_by_rays): the same figures, so the
// images agree but where a shadow narrower than a pixel falls between two
// samples (measured at 96x72, --aa 4: RMS 0.00007 to 0.00077; the
// rays sampled like a mirror's span, before: 0.0022 to 0.0070).
TEST(ShadowPass, RaysAndVolumesRenderTheSameShadows) {
  for (const char* name : {"d_spheres_2lights.json", "a_glass.json", "c_thermometer.json"}) {
    SCOPED_TRACE(name);
    const Scene scene = paper_scene(name, 96, 72);
    auto vol0 = render_image(scene, iv(0, ShadowPass::kVolumes));
    auto ray0 = render_image(scene, iv(0, ShadowPass::kRays));
    ASSERT_TRUE(vol0.ok() && ray0.ok());
    int differ = 0;
    for (size_t i = 0; i < vol0->pixels.rgb.size(); ++i)
      differ += std::abs(vol0->pixels.rgb[i] - ray0->pixels.rgb[i]) > 2.0 / 255;
    EXPECT_LE(differ, 96 * 72 * 3 / 100) << "point sampled: " << differ << " values differ";
    EXPECT_LT(difference(vol0->pixels, ray0->pixels).first, 1e-3);

    RenderParams dense;
    dense.spp = 8;
    dense.threads = 2;
    auto ref = render_image(scene, dense);
    auto vol4 = render_image(scene, iv(4, ShadowPass::kVolumes));
    auto ray4 = render_image(scene, iv(4, ShadowPass::kRays));
    ASSERT_TRUE(ref.ok() && vol4.ok() && ray4.ok());
    const double ev = difference(vol4->pixels, ref->pixels).first;
    const double er = difference(ray4->pixels, ref->pixels).first;
    EXPECT_LT(er, 1.1 * ev + 0.0005) << "--aa 4 against --spp 8: volumes " << ev << ", rays " << er;
    EXPECT_LT(difference(vol4->pixels, ray4->pixels).first, 0.0015) << "--aa 4: rays and volumes";
  }
}

// Shadows by rays on spans narrower than the sub-scanlines' spacing h = 1/N
// pixel: one shadow ray per light at the span's middle, no end probes or
// bisection (sub_line.cpp figures_by_rays), as supersampling at spacing h
// samples them. On a grid of triangles about 1/8 pixel wide, with relief
// so that faces shadow their neighbours, at --aa 4: about one shadow ray
// per span instead of three, and an image closer to a dense reference than
// supersampling's 4 x 4 samples per pixel (measured: volumes 0.0132,
// rays 0.0182, and 0.0150 with end probes on every span).
TEST(ShadowPass, NarrowSpansCastOneRayPerLightAtTheirMidpoint) {
  const Scene fine = grid_scene(240, 64);
  auto ray4 = render_image(fine, iv(4, Visibility::kScanline, ShadowPass::kRays));
  RenderParams dense, super;
  dense.spp = 8;
  super.spp = 4;
  dense.threads = super.threads = 2;
  auto ref = render_image(fine, dense);
  auto ss4 = render_image(fine, super);
  ASSERT_TRUE(ray4.ok() && ref.ok() && ss4.ok());
  const double per_span =
      static_cast<double>(ray4->stats.rays_shadow) / static_cast<double>(ray4->stats.spans_total);
  EXPECT_LT(per_span, 1.2) << ray4->stats.rays_shadow << " rays, " << ray4->stats.spans_total
                           << " spans";
  const double er = difference(ray4->pixels, ref->pixels).first;
  const double es = difference(ss4->pixels, ref->pixels).first;
  EXPECT_LT(er, es) << "against --spp 8: --aa 4 by rays " << er << ", --spp 4 " << es;
  std::printf("shadow rays per span %.3f; against --spp 8: --aa 4 %.5f, --spp 4 %.5f\n",
              per_span, er, es);
}

// A light on the far side of a flat face from the eye, or any light on a
// face whose material has no diffuse or specular term, lights nothing
// there (Tracer::shade): shadows by rays cast it no ray. A square facing
// the eye, lit from the eye's side; a second light behind it adds no ray
// and changes no pixel of the square.
TEST(ShadowPass, RaysSkipLightsThatCannotLightTheFace) {
  auto square = [](bool behind, const char* surface) {
    std::ostringstream nff;
    nff << "v\nfrom 0 -3 0\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution 48 48\n"
           "b 0 0 0\nl 1 -2 1\n";
    if (behind) nff << "l 0 2 0\n";
    nff << "f " << surface << "\np 4\n-0.5 0 -0.5\n0.5 0 -0.5\n0.5 0 0.5\n-0.5 0 0.5\n";
    // A small occluder between the square and the front light.
    nff << "f 0.9 0.9 0.9 1 0 0 0 1\np 4\n0.1 -0.8 0\n0.3 -0.8 0\n0.3 -0.8 0.2\n0.1 -0.8 0.2\n";
    auto scene = parse_nff(nff.str(), "square.nff");
    EXPECT_TRUE(scene.ok()) << scene.status().message();
    return scene.ok() ? *scene : Scene{};
  };
  const RenderParams p = iv(4, Visibility::kScanline, ShadowPass::kRays);
  auto one = render_image(square(false, "0.3 0.7 0.9 1 0 0 0 1"), p);
  auto two = render_image(square(true, "0.3 0.7 0.9 1 0 0 0 1"), p);
  auto dark = render_image(square(true, "0.3 0.7 0.9 0 0 0 0 1"), p);
  ASSERT_TRUE(one.ok() && two.ok() && dark.ok());
  EXPECT_GT(one->stats.rays_shadow, 0u);
  EXPECT_EQ(two->stats.rays_shadow, one->stats.rays_shadow) << "the light behind the square";
  EXPECT_LT(dark->stats.rays_shadow, one->stats.rays_shadow / 4)
      << "kd = ks = 0: only the occluder's own spans cast rays";
  auto vol = render_image(square(true, "0.3 0.7 0.9 1 0 0 0 1"),
                          iv(4, Visibility::kScanline, ShadowPass::kVolumes));
  ASSERT_TRUE(vol.ok());
  EXPECT_LT(difference(two->pixels, vol->pixels).first, 1e-3) << "rays and volumes";
}

// auto (the default): rays where the occluders in view times the lights
// reach 8 per image row (docs/renderer.md "Shadows by rays"), volumes
// otherwise; the same scene at a larger size builds volumes again, and the
// farm's smaller cost preview builds what its frame will.
TEST(ShadowPass, AutoCastsRaysWhereTheOccludersAndLightsOutnumberTheRows) {
  Scene fine = grid_scene(60, 64);  // 7,201 primitives, 1 light: 112 per row
  Scene coarse = fine;              // 7 per row
  coarse.camera.width = coarse.camera.height = 1024;
  // Each occluder has a volume per light: with a second light the coarse
  // frame's 7 per row count as 14.
  Scene lit = coarse;
  lit.lights.push_back(lit.lights.front());
  lit.lights.back().position.x = -lit.lights.back().position.x;
  EXPECT_EQ(frame_passes(lit, iv(4)).shadows, ShadowPass::kRays);
  const Scene d = paper_scene("d_spheres_2lights.json", 64, 48);
  for (int aa : {0, 4}) {
    SCOPED_TRACE("aa " + std::to_string(aa));
    RenderParams scan = iv(aa, Visibility::kScanline);
    auto f = prepare_scene(fine, scan);
    auto c = prepare_scene(coarse, scan);
    auto pd = prepare_scene(d, scan);
    ASSERT_TRUE(f.ok() && c.ok() && pd.ok());
    EXPECT_FALSE((*f)->volumes);
    EXPECT_TRUE((*c)->volumes);
    EXPECT_TRUE((*pd)->volumes) << "the paper's scene keeps the paper's volumes";
    EXPECT_EQ(frame_passes(fine, scan).shadows, ShadowPass::kRays);
    EXPECT_EQ(frame_passes(coarse, scan).shadows, ShadowPass::kVolumes);
    const BandResult r = render_band(**f, Band{0, 64}, scan);
    EXPECT_EQ(r.stats.shadow_method, "rays");
    EXPECT_EQ(r.stats.visibility, "scanline");
    EXPECT_EQ(r.stats.tests_shadow_volume, 0u);
  }
  // The farm's preview of the coarse frame is kPreviewRows (64) rows, the
  // size of `fine`, where auto alone would choose rays: it renders with the
  // frame's passes (frame_passes), volumes.
  EXPECT_EQ(kPreviewRows, fine.camera.height);
  EXPECT_EQ(frame_passes(coarse, iv(4)).shadows, ShadowPass::kVolumes);
  EXPECT_EQ(frame_passes(coarse, iv(4, ShadowPass::kRays)).shadows, ShadowPass::kRays);
  auto costs = predict_row_costs(coarse, iv(4), 1);
  ASSERT_TRUE(costs.ok()) << costs.status().message();
  EXPECT_EQ(costs->size(), 1024u);
}

}  // namespace
}  // namespace locus
