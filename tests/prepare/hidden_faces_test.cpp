// The back faces of closed convex solids (common/prepare/hidden_faces.h):
// which polygons make such solids, which rays may skip which faces (held
// against rays cast here), and that leaving them out changes no image.
#include "common/prepare/hidden_faces.h"

#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/prepare/scan_scene.h"
#include "common/render.h"
#include "common/scan/scanline.h"
#include "common/scene/scene_io.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

using Tri = std::vector<Vec3>;

// A tetrahedron's four faces, counter-clockwise seen from outside (or
// clockwise with `inward`).
std::vector<Tri> tetra(const Vec3& c, double r, bool inward = false) {
  const Vec3 a = c + r * Vec3(1, 1, 1), b = c + r * Vec3(1, -1, -1), d = c + r * Vec3(-1, 1, -1),
             e = c + r * Vec3(-1, -1, 1);
  std::vector<Tri> f = {{a, e, b}, {a, b, d}, {a, d, e}, {b, e, d}};
  if (inward) {
    for (Tri& t : f) std::swap(t[1], t[2]);
  }
  return f;
}

std::vector<Tri> cube(const Vec3& c, double r) {
  auto p = [&](int x, int y, int z) { return c + r * Vec3(x, y, z); };
  return {{p(-1, -1, -1), p(-1, 1, -1), p(1, 1, -1), p(1, -1, -1)},
          {p(-1, -1, 1), p(1, -1, 1), p(1, 1, 1), p(-1, 1, 1)},
          {p(-1, -1, -1), p(1, -1, -1), p(1, -1, 1), p(-1, -1, 1)},
          {p(-1, 1, -1), p(-1, 1, 1), p(1, 1, 1), p(1, 1, -1)},
          {p(-1, -1, -1), p(-1, -1, 1), p(-1, 1, 1), p(-1, 1, -1)},
          {p(1, -1, -1), p(1, 1, -1), p(1, 1, 1), p(1, -1, 1)}};
}

struct Group {
  std::string material;  // an NFF "f" line
  std::vector<Tri> faces;
};

Scene scene_of(const std::vector<Group>& groups, const std::string& camera,
               const std::string& lights = "l 4 -6 5\n") {
  std::ostringstream nff;
  nff.precision(17);
  nff << camera << "b 0.1 0.2 0.3\n" << lights;
  for (const Group& g : groups) {
    nff << g.material << '\n';
    for (const Tri& t : g.faces) {
      nff << "p " << t.size() << '\n';
      for (const Vec3& v : t) nff << v.x << ' ' << v.y << ' ' << v.z << '\n';
    }
  }
  auto scene = parse_nff(nff.str(), "solids.nff");
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  return scene.ok() ? *scene : Scene{};
}

const char* kCamera =
    "v\nfrom 1 -9 3\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution 64 64\n";
const char* kMatte = "f 0.8 0.6 0.4 1 0 0 0 1";
const char* kGlass = "f 0.9 0.9 0.9 0 0.1 0 0.9 1.5";

std::set<int> solid_faces(const ClosedSolids& s) { return {s.faces.begin(), s.faces.end()}; }

TEST(ClosedSolids, OnlyClosedConsistentConvexSolidsAreFound) {
  std::vector<Tri> faces;
  auto add = [&](const std::vector<Tri>& f) {
    const int first = static_cast<int>(faces.size());
    faces.insert(faces.end(), f.begin(), f.end());
    return first;
  };
  const int closed = add(tetra(Vec3(-3, 0, 0), 0.5));
  const int inward = add(tetra(Vec3(-1.5, 0, 0), 0.5, true));
  std::vector<Tri> open = tetra(Vec3(0, 0, 0), 0.5);
  open.pop_back();  // three faces: a border
  add(open);
  std::vector<Tri> reversed = tetra(Vec3(1.5, 0, 0), 0.5);
  std::swap(reversed[2][1], reversed[2][2]);  // one face walked the wrong way
  add(reversed);
  const int box = add(cube(Vec3(3, 0, 0), 0.5));
  // A bipyramid whose apices do not stand over its base: closed, concave.
  const Vec3 a(-1, 3, 0), b(1, 3, 0), c(0, 4, 0), top(2.5, 3.2, 1), bottom(2.5, 3.2, -1);
  add({{a, b, top}, {b, c, top}, {c, a, top}, {b, a, bottom}, {c, b, bottom}, {a, c, bottom}});
  // Two sides of one sheet: closed, no volume.
  add({{Vec3(0, -3, 0), Vec3(1, -3, 0), Vec3(0, -3, 1)},
       {Vec3(0, -3, 0), Vec3(0, -3, 1), Vec3(1, -3, 0)}});
  // Two tetrahedra touching at a vertex (SPD tetra's): two solids.
  const int touch_a = add(tetra(Vec3(-3, 3, 0), 0.5));
  const int touch_b = add(tetra(Vec3(-2, 4, 1), 0.5));

  const Scene scene = scene_of({{kMatte, faces}}, kCamera);
  const PrimitiveSet set = build_primitives(scene);
  ASSERT_EQ(set.prims.size(), faces.size());
  const ClosedSolids s = closed_convex_solids(set);
  std::set<int> expect;
  for (int first : {closed, inward, touch_a, touch_b})
    for (int k = 0; k < 4; ++k) expect.insert(first + k);
  for (int k = 0; k < 6; ++k) expect.insert(box + k);
  EXPECT_EQ(solid_faces(s), expect);
  ASSERT_EQ(s.count(), 5);
  for (int i = 0; i < s.count(); ++i) {
    // Each solid's faces are one of the groups above, whole.
    const int f0 = s.faces[s.first[i]];
    EXPECT_EQ(s.first[i + 1] - s.first[i], f0 == box ? 6 : 4);
    EXPECT_EQ(s.sign[i], f0 == inward ? -1.0 : 1.0) << "solid of face " << f0;
  }
}

// Does the ray from `from` towards `to` meet a primitive of `among` other
// than `self` before it reaches `to`?
bool blocked(const PrimitiveSet& set, const std::vector<int>& among, int self, const Vec3& from,
             const Vec3& to) {
  const Ray r{from, to - from};
  for (int p : among) {
    if (p != self && intersect_nearest(set, p, r, 1e-9, 1.0 - 1e-9)) return true;
  }
  return false;
}

Vec3 centroid(const PolygonPrim& p) {
  Vec3 c(0.0);
  for (const Vec3& v : p.verts) c += v;
  return c / static_cast<double>(p.verts.size());
}

TEST(ClosedSolids, EyeAndLightCullsAreTheFacesTheirOwnSolidHides) {
  std::vector<Tri> solids;
  for (int i = 0; i < 5; ++i) {
    const std::vector<Tri> t = tetra(Vec3(-2 + i, 0.3 * i, 0.2 * i), 0.4, i % 2 == 1);
    solids.insert(solids.end(), t.begin(), t.end());
  }
  const std::vector<Tri> box = cube(Vec3(0, 2, 0), 0.5);
  solids.insert(solids.end(), box.begin(), box.end());
  const Scene scene = scene_of({{kMatte, solids}}, kCamera, "l 4 -6 5\nl -5 1 -4\n");
  const PreparedScene ps(scene, RenderParams{});
  const ClosedSolids s = closed_convex_solids(ps.prims);
  ASSERT_EQ(s.count(), 6);
  int eye = 0, light0 = 0, light1 = 0;
  for (int i = 0; i < s.count(); ++i) {
    const std::vector<int> own(s.faces.begin() + s.first[i], s.faces.begin() + s.first[i + 1]);
    for (int f : own) {
      // Culled exactly where the solid's other faces stand between the
      // face's centre and the eye (or the light).
      const Vec3 c = centroid(ps.prims.polygons[ps.prims.prims[f].index]);
      const uint8_t cull = ps.culls[f];
      EXPECT_EQ((cull & kCullEye) != 0, blocked(ps.prims, own, f, ps.camera.from, c)) << f;
      for (int j = 0; j < 2; ++j) {
        EXPECT_EQ((cull & cull_light(j)) != 0,
                  blocked(ps.prims, own, f, scene.lights[j].position, c))
            << f << " light " << j;
      }
      eye += (cull & kCullEye) != 0;
      light0 += (cull & cull_light(0)) != 0;
      light1 += (cull & cull_light(1)) != 0;
    }
  }
  EXPECT_GT(eye, 0);
  EXPECT_GT(light0, 0);
  EXPECT_GT(light1, 0);
}

TEST(ClosedSolids, NoCullsWhereTheyCouldBeWrong) {
  const std::vector<Tri> t = tetra(Vec3(0, 0, 0), 1.0);
  // Glass passes the light through both sides: no light culls, eye culls stay.
  {
    const PreparedScene ps(scene_of({{kGlass, t}}, kCamera), RenderParams{});
    int eye = 0;
    for (uint8_t c : ps.culls) {
      EXPECT_EQ(c & ~kCullEye, 0);
      eye += c & kCullEye;
    }
    EXPECT_GT(eye, 0);
  }
  // The light inside the solid: every face is lit from behind its plane.
  {
    const PreparedScene ps(scene_of({{kMatte, t}}, kCamera, "l 0.1 0 0\n"), RenderParams{});
    for (uint8_t c : ps.culls) EXPECT_EQ(c & cull_light(0), 0);
  }
  // The eye inside the solid, or the solid cut by hither's sphere: no eye
  // culls.
  for (const char* cam :
       {"v\nfrom 0.1 0 0\nat 1 1 0\nup 0 0 1\nangle 40\nhither 0.01\nresolution 64 64\n",
        "v\nfrom 0 -3 0\nat 0 0 0\nup 0 0 1\nangle 40\nhither 2.5\nresolution 64 64\n"}) {
    const PreparedScene ps(scene_of({{kMatte, t}}, cam), RenderParams{});
    for (uint8_t c : ps.culls) EXPECT_EQ(c & kCullEye, 0) << cam;
  }
}

TEST(ClosedSolids, ShadowRaysSkipTheirOwnSolidOnlyWhereItCannotBeMet) {
  // Five solids, one glass, and two tetrahedra whose faces interleave (no
  // run of consecutive primitives); two lights.
  std::vector<Tri> matte;
  for (int i = 0; i < 3; ++i) {
    const std::vector<Tri> t = tetra(Vec3(-2 + 1.2 * i, 0.3 * i, 0.2 * i), 0.4, i == 1);
    matte.insert(matte.end(), t.begin(), t.end());
  }
  const std::vector<Tri> box = cube(Vec3(0, 2, 0), 0.5);
  matte.insert(matte.end(), box.begin(), box.end());
  const int interleaved = static_cast<int>(matte.size());
  const std::vector<Tri> ta = tetra(Vec3(2, 0, 0), 0.3), tb = tetra(Vec3(2, 1, 1), 0.3);
  for (int q = 0; q < 4; ++q) {
    matte.push_back(ta[q]);
    matte.push_back(tb[q]);
  }
  const int glass = static_cast<int>(matte.size());
  const Scene scene = scene_of({{kMatte, matte}, {kGlass, tetra(Vec3(0, -2, 0), 0.5)}}, kCamera,
                               "l 4 -6 5\nl -5 1 -4\n");
  const PreparedScene ps(scene, RenderParams{});
  ASSERT_EQ(closed_convex_solids(ps.prims).count(), 7);
  ASSERT_EQ(ps.own_solid.size(), ps.prims.prims.size());
  int skips = 0;
  for (int f = 0; f < static_cast<int>(ps.prims.prims.size()); ++f) {
    const OwnSolid& o = ps.own_solid[f];
    if (f >= interleaved) {
      EXPECT_EQ(o.count, 0) << f;  // not consecutive, or glass
      continue;
    }
    const int first = f < 12 ? f / 4 * 4 : 12;
    // The face's outward normal, found apart: away from the solid's centre.
    const PolygonPrim& poly = ps.prims.polygons[ps.prims.prims[f].index];
    Vec3 centre(0.0);
    const int nf = f < 12 ? 4 : 6;
    for (int g = first; g < first + nf; ++g)
      centre += centroid(ps.prims.polygons[ps.prims.prims[g].index]) / double(nf);
    const Vec3 c = centroid(poly);
    const Vec3 out = glm::dot(poly.normal, c - centre) > 0 ? poly.normal : -poly.normal;
    bool any = false;
    for (int j = 0; j < 2; ++j) {
      const Vec3 light = scene.lights[j].position;
      const bool front = glm::dot(out, light - c) > 0;
      EXPECT_EQ((o.lights >> j & 1) != 0, front) << f << " light " << j;
      any = any || front;
      const PrimRange in = own_solid_skip(ps.own_solid, f, j);
      if (!front) {
        EXPECT_EQ(in.count, 0) << f;
        continue;
      }
      EXPECT_EQ(in.first, first);
      EXPECT_EQ(in.count, nf);
      for (int g = first; g < first + nf; ++g) EXPECT_TRUE(in.has(g));
      EXPECT_FALSE(in.has(first - 1));
      EXPECT_FALSE(in.has(first + nf));
      ++skips;
    }
    // A face turned away from every light has no entry.
    EXPECT_EQ(o.count, any ? nf : 0) << f;
    if (any) {
      EXPECT_EQ(o.first, first) << f;
    }
    // No receiver, or a light past the table: nothing skipped.
    EXPECT_EQ(own_solid_skip(ps.own_solid, -1, 0).count, 0);
    EXPECT_EQ(own_solid_skip(ps.own_solid, f, kOwnSolidLights).count, 0);
  }
  EXPECT_GT(skips, 10);
  EXPECT_LT(glass, static_cast<int>(ps.prims.prims.size()));
  // A light all but in a face's plane (1e-12 in front of it, where rounding
  // could put a shadow ray's origin behind the face): that face skips
  // nothing for it; one well in front does.
  {
    const std::vector<Tri> t = tetra(Vec3(0, 0, 0), 1.0);
    const Vec3 n = glm::normalize(glm::cross(t[0][1] - t[0][0], t[0][2] - t[0][0]));
    const Vec3 at = t[0][0] + 5.0 * (t[0][1] - t[0][0]);  // in face 0's plane
    for (double d : {1e-12, 1e-3}) {
      std::ostringstream light;
      light.precision(17);
      const Vec3 l = at + d * n;
      light << "l " << l.x << ' ' << l.y << ' ' << l.z << '\n';
      const PreparedScene near(scene_of({{kMatte, t}}, kCamera, light.str()), RenderParams{});
      ASSERT_FALSE(near.own_solid.empty());
      EXPECT_EQ(own_solid_skip(near.own_solid, 0, 0).count, d > 1e-6 ? 4 : 0) << d;
    }
  }
  // Nothing to skip in a scene of glass alone: no table.
  const PreparedScene clear(scene_of({{kGlass, tetra(Vec3(0, 0, 0), 1.0)}}, kCamera),
                            RenderParams{});
  EXPECT_TRUE(clear.own_solid.empty());
}

// The scene prepared with no own-solid skips (own_solids) in its geometry.
std::unique_ptr<PreparedScene> without_own_solids(const Scene& scene, const RenderParams& p) {
  auto geometry = std::make_shared<SceneGeometry>(scene, p);
  geometry->own_solid.clear();
  return std::make_unique<PreparedScene>(std::move(geometry), scene.camera, p);
}

TEST(ClosedSolids, ShadowRaysSkippingTheirOwnSolidMakeTheSameImages) {
  const RenderParams traced = testing_util::raytrace_params(1);
  const RenderParams rays = testing_util::shadow_rays_params(2);
  for (const char* path : {"/spd/def/tetra.nff", "/spd/s1/tetra.nff"}) {
    for (const RenderParams& params : {traced, rays}) {
      auto scene = load_scene(std::string(LOCUS_SHARED_DIR) + path);
      ASSERT_TRUE(scene.ok()) << scene.status().message();
      scene->camera.width = scene->camera.height = 96;
      const PreparedScene with(*scene, params);
      ASSERT_FALSE(with.own_solid.empty()) << path;
      const auto without = without_own_solids(*scene, params);
      ASSERT_TRUE(without->own_solid.empty()) << path;
      const BandResult x = render_band(with, Band{0, 96}, params);
      const BandResult y = render_band(*without, Band{0, 96}, params);
      EXPECT_EQ(testing_util::max_difference(x.pixels, y.pixels), 0.0) << path;
      EXPECT_EQ(x.stats.rays_shadow, y.stats.rays_shadow) << path;
      EXPECT_GT(x.stats.rays_shadow, 0) << path;
      // SPD tetra's shadow rays test about half as many faces (level 9 at
      // 512x512: 4.0 M -> 2.1 M).
      EXPECT_LT(x.stats.tests_ray_object, y.stats.tests_ray_object) << path;
    }
  }
}

// The same scene prepared twice, the second time without culls.
struct WithAndWithout {
  std::unique_ptr<PreparedScene> culled, plain;
  WithAndWithout(const Scene& scene, const RenderParams& p)
      : culled(std::make_unique<PreparedScene>(scene, p)), plain(without_own_solids(scene, p)) {
    plain->culls.assign(plain->culls.size(), 0);
    if (plain->scan && !plain->by_rays)
      plain->scan = std::make_unique<ScanScene>(build_scan_scene(*plain, p.aa > 0, 1));
  }
};

RenderParams config_iv(int aa) { return testing_util::config_iv_params(aa, 1); }

TEST(ClosedSolids, SpdTetraHidesHalfItsFacesAndTheVisibleSegmentsAreUnchanged) {
  auto scene = load_scene(LOCUS_SHARED_DIR "/spd/def/tetra.nff");
  ASSERT_TRUE(scene.ok()) << scene.status().message();
  scene->camera.width = scene->camera.height = 128;
  const RenderParams p = config_iv(4);
  const WithAndWithout w(*scene, p);
  ASSERT_TRUE(w.culled->scan && !w.culled->by_rays);
  const ScanScene& a = *w.culled->scan;
  const ScanScene& b = *w.plain->scan;
  EXPECT_EQ(b.faces.size(), w.culled->prims.prims.size());
  // 1,024 tetrahedra: each turns one to three of its faces away.
  EXPECT_GT(a.faces.size(), b.faces.size() / 4);
  EXPECT_LT(a.faces.size(), b.faces.size() * 3 / 4);
  VisibleScratch sa, sb;
  std::vector<VisibleSegment> va, vb;
  int lines = 0, hidden_met = 0;
  for (int row = 0; row < 128; ++row) {
    for (int k = 0; k < 4; ++k) {
      const double y = row + (k + 0.5) / 4;
      visible_segments(a, w.culled->camera, y, a.cover[row], sa, va);
      visible_segments(b, w.plain->camera, y, b.cover[row], sb, vb);
      // Each face's visible length on the line: the same, but for slivers
      // of a back face at a silhouette, where it meets the front face at
      // the same depth (a tie).
      std::map<int, double> la, lb;
      for (const VisibleSegment& g : va) la[g.face < 0 ? -1 : a.faces[g.face].prim] += g.x1 - g.x0;
      for (const VisibleSegment& g : vb) lb[g.face < 0 ? -1 : b.faces[g.face].prim] += g.x1 - g.x0;
      for (const auto& [prim, len] : lb) {
        const double other = la.count(prim) ? la[prim] : 0.0;
        ASSERT_NEAR(len, other, 1e-9) << "line y = " << y << ", prim " << prim;
        if (prim >= 0 && (w.culled->culls[prim] & kCullEye)) ++hidden_met;
      }
      for (const auto& [prim, len] : la) ASSERT_TRUE(lb.count(prim)) << prim;
      lines += !va.empty();
    }
  }
  EXPECT_GT(lines, 100);
  // Without culls, back faces do show, as slivers, now and then: the
  // comparison meets them.
  EXPECT_GT(hidden_met, 0);
}

TEST(ClosedSolids, ImagesWithCullsEqualImagesWithout) {
  struct Case {
    const char* path;
    RenderParams params;
    bool counts_tests;  // shadow or eye rays are cast (configuration IV may use volumes)
  };
  const RenderParams traced = testing_util::raytrace_params(1);
  const RenderParams rays = testing_util::shadow_rays_params(2);
  for (const Case& c :
       {Case{"/spd/def/tetra.nff", config_iv(4), false}, Case{"/spd/def/tetra.nff", traced, true},
        Case{"/spd/s1/tetra.nff", rays, true}, Case{"/spd/def/tetra.nff", config_iv(0), false}}) {
    auto scene = load_scene(std::string(LOCUS_SHARED_DIR) + c.path);
    ASSERT_TRUE(scene.ok()) << scene.status().message();
    scene->camera.width = scene->camera.height = 96;
    const WithAndWithout w(*scene, c.params);
    int culled = 0;
    for (const uint8_t c : w.culled->culls) culled += c != 0;
    EXPECT_GT(culled, 0) << c.path;
    const BandResult x = render_band(*w.culled, Band{0, 96}, c.params);
    const BandResult y = render_band(*w.plain, Band{0, 96}, c.params);
    EXPECT_EQ(testing_util::max_difference(x.pixels, y.pixels), 0.0) << c.path;
    // Fewer tests where faces were skipped. The ray tracer casts the same
    // rays; the local method traces a sample whose face it cannot hit
    // (hit_on_face), which a back face's sliver at a silhouette was now
    // and then: no more rays.
    if (c.counts_tests) {
      EXPECT_LT(x.stats.tests_ray_object, y.stats.tests_ray_object) << c.path;
    }
    if (c.params.method == Method::kRaytrace) {
      EXPECT_EQ(x.stats.rays_shadow, y.stats.rays_shadow) << c.path;
      EXPECT_EQ(x.stats.rays_eye, y.stats.rays_eye) << c.path;
    } else {
      EXPECT_LE(x.stats.rays_shadow, y.stats.rays_shadow) << c.path;
      EXPECT_LE(x.stats.rays_eye, y.stats.rays_eye) << c.path;
    }
  }
}

}  // namespace
}  // namespace locus
