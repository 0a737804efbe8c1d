// t_pj at single points and on scanline spans, against shadow rays
// (docs/shadow-volumes.md): a convex receiver skipping itself, receivers
// cut into slices, and the exact shadow intervals of spheres and cones.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include "common/prepare/prepared.h"
#include "common/prepare/shadow_volume.h"
#include "common/render.h"
#include "common/scan/scanline.h"
#include "common/scan/span_shadows.h"
#include "common/trace/raytrace.h"
#include "common/trace/shadow_search.h"
#include "tests/trace/shadow_scenes.h"

namespace locus {
namespace {

// beyond_support (a receiver skipping itself): wherever it says the plane
// touching a sphere's or cone's solid has the origin and the light in
// front, the segment between them meets no surface of it. Points just
// outside the surfaces, facing the light, and points anywhere else.
TEST(ShadowVolume, BeyondTheSupportingPlaneNothingIsHit) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1), h(0, 1);
  Scene s;
  for (int k = 0; k < 60; ++k) {
    const Vec3 c(u(rng), u(rng), u(rng));
    const Vec3 d(u(rng), u(rng), u(rng));
    const double r = 0.1 + 0.5 * h(rng);
    Object o;
    switch (k % 4) {
      case 0:
        o.shape = Sphere{c, r};
        break;
      case 1:
        o.shape = Cone{c, r, c + d, r, k % 8 == 1};
        break;
      case 2:
        o.shape = Cone{c, r, c + d, 0.0, false};
        break;
      default:  // widening
        o.shape = Cone{c, 0.05 * r, c + d, r, k % 8 == 3};
        break;
    }
    s.objects.push_back(o);
  }
  const PrimitiveSet set = build_primitives(s);
  int skipped = 0, near_surface = 0;
  for (int prim = 0; prim < static_cast<int>(set.prims.size()); ++prim) {
    const Aabb& box = set.bounds[prim];
    for (int i = 0; i < 4000; ++i) {
      const Vec3 light = 3.0 * Vec3(u(rng), u(rng), u(rng));
      Vec3 o = 2.0 * Vec3(u(rng), u(rng), u(rng));
      if (i % 2) {
        // Just off the surface: the nearest crossing along a ray aimed
        // into the body's box.
        const Vec3 aim = box.lo + Vec3(h(rng), h(rng), h(rng)) * (box.hi - box.lo);
        const Ray probe{o, glm::normalize(aim - o)};
        const auto c = intersect_nearest(set, prim, probe, 0.0, kInf);
        if (!c) continue;
        const Vec3 p = probe.origin + c->t * probe.dir;
        o = p + (glm::dot(c->normal, light - p) >= 0 ? 1e-7 : -1e-7) * c->normal;
      }
      if (!beyond_support(set, prim, o, light)) continue;
      ++skipped;
      near_surface += i % 2;
      ASSERT_FALSE(intersect_any(set, prim, Ray{o, light - o}, 0.0, 1.0))
          << "primitive " << prim << " origin (" << o.x << ", " << o.y << ", " << o.z << ")";
    }
  }
  std::printf("beyond the supporting plane: %d segments, %d from the surface\n", skipped,
              near_surface);
  EXPECT_GT(near_surface, 20000);
}

// A long cylinder as a receiver is cut into slices, each searching only the
// occluders that reach it (ReceiverParts). Points all over its surface,
// near the slices' boundaries and just past its ends included, get the
// very same t_pj as a shadow ray gives, and as the whole candidate list.
TEST(ShadowVolumeScenes, ReceiverSlicesGiveTheShadowRaysTransmittance) {
  Scene s = floor_scene(Vec3(0.5, 6, 1.5));
  s.lights.push_back(Light{Vec3(-5, 3, -2), std::nullopt});
  s.lights.push_back(Light{Vec3(6, 0.8, 0.3), std::nullopt});
  Material glass;
  glass.kd = 0.1;
  glass.t = 0.8;
  glass.ior = 1.5;
  glass.absorption = Color(0.1, 0.2, 0.4);
  s.materials.push_back(glass);
  const int glass_material = static_cast<int>(s.materials.size()) - 1;
  const Vec3 base(-4, 1, 0), apex(4, 1.3, 0.2);
  Object cyl;
  cyl.shape = Cone{base, 0.25, apex, 0.25, false};
  s.objects.push_back(cyl);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1), h(0, 1);
  for (int k = 0; k < 24; ++k) {
    // Occluders above, beside and below the cylinder, along its length.
    const Vec3 c(4.5 * u(rng), 1.2 + 1.5 * u(rng), 1.2 * u(rng));
    if (glm::length(glm::vec<2, double>(c.y - 1.15, c.z - 0.1)) < 0.7) continue;
    Object o;
    o.material = k % 4 == 0 ? glass_material : 0;
    if (k % 3 == 0) {
      o.shape = Sphere{c, 0.1 + 0.3 * h(rng)};
    } else if (k % 3 == 1) {
      o.shape = Cone{c, 0.1 + 0.1 * h(rng), c + Vec3(u(rng), u(rng), u(rng)), 0.1 * h(rng), false};
    } else {
      o.shape = make_box(c - Vec3(0.1 + 0.3 * h(rng)), c + Vec3(0.1 + 0.3 * h(rng)));
    }
    s.objects.push_back(o);
  }
  // A thin slab whose shadow from light 0 falls across the middle slice
  // boundary (t = 1/2): a slice that stopped short of it would lose it.
  s.objects.push_back(box_object(Vec3(0.189, 2.95, 0.234), Vec3(0.193, 3.05, 1.034)));
  RenderParams rt;
  auto ref = prepare_scene(s, rt);
  auto iv = prepare_scene(s, config_iv());
  ASSERT_TRUE(ref.ok() && iv.ok());
  const PreparedScene& ps = **iv;
  int receiver = -1;
  for (int i = 0; i < static_cast<int>(ps.prims.prims.size()); ++i) {
    if (ps.prims.prims[i].object == 1) receiver = i;
  }
  ASSERT_GE(receiver, 0);
  ASSERT_EQ(ps.volumes->parts.size(), ps.prims.prims.size());
  const int slices = ps.volumes->parts[receiver].count;
  ASSERT_GE(slices, 2) << "the cylinder is not cut, the test proves nothing";
  Stats rs, vs;
  Tracer tracer(**ref, rs);
  const Vec3 d = apex - base;
  const Vec3 a = glm::normalize(d);
  const Vec3 e1 = any_perpendicular(a), e2 = glm::cross(a, e1);
  int shadowed = 0, lit = 0, tinted = 0, compared = 0;
  for (int i = 0; i < 30000; ++i) {
    // Half the points within 1e-9 of a slice boundary (or an end).
    double t = h(rng);
    if (i % 2) t = std::round(t * slices) / slices + 1e-9 * u(rng);
    t = std::clamp(t, 0.0, 1.0);
    const double phi = 2 * std::numbers::pi * h(rng);
    const Vec3 n = std::cos(phi) * e1 + std::sin(phi) * e2;
    const Vec3 p = base + t * d + 0.25 * n;
    for (int light = 0; light < static_cast<int>(s.lights.size()); ++light) {
      if (glm::dot(n, s.lights[light].position - p) <= 0) continue;  // facing away
      const Color want = tracer.transmittance(p, n, light);
      const Vec3 origin = p + ps.eps * n;
      ASSERT_EQ(volume_transmittance(ps, origin, light, receiver, vs), want)
          << "t " << t << " phi " << phi << " light " << light;
      ASSERT_EQ(volume_transmittance(ps, origin, light, -1, vs), want)
          << "t " << t << " phi " << phi << " light " << light << " (no receiver)";
      ++compared;
      shadowed += want == Color(0.0);
      lit += want == Color(1.0);
      tinted += want != Color(0.0) && want != Color(1.0);
    }
  }
  std::printf("cylinder in %d slices: %d points, %d shadowed, %d tinted, %d lit\n", slices,
              compared, shadowed, tinted, lit);
  EXPECT_GT(shadowed, 1000);
  EXPECT_GT(tinted, 100);
  EXPECT_GT(lit, 1000);
}

// Opaque spheres and cones between a floor and its lights get exact
// intervals on each sub-scanline (span_shadows.cpp, Pencil): no point of
// the floor is then uncertain, and every point's state is what a shadow
// ray says, right up to the intervals' ends. The bodies include tubes seen
// along their axis from a light (its light passes through the bore: a
// shadow with a hole, whose edges are rim events), cones, frustums, capped
// ones, tubes tilted every way, and a sphere beyond one light.
TEST(ShadowVolumeScenes, CurvedOccludersGetExactIntervals) {
  Scene s = floor_scene(Vec3(0.3, 7, 0.4));
  s.lights.push_back(Light{Vec3(-3, 5, -1), std::nullopt});
  s.camera.width = 80;
  s.camera.height = 60;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), h(0, 1);
  auto add = [&](Shape shape) {
    Object o;
    o.shape = std::move(shape);
    s.objects.push_back(o);
  };
  // Tubes pointing at light 0: its light goes through their bores.
  for (const Vec3& c : {Vec3(-1.5, 2.0, 1.0), Vec3(1.6, 1.5, -1.2)}) {
    const Vec3 a = glm::normalize(s.lights[0].position - c);
    add(Cone{c - 0.4 * a, 0.35, c + 0.4 * a, 0.35, false});
  }
  // Above light 1 (and below light 0): it shadows the floor from light 0
  // only.
  add(Sphere{Vec3(-2.5, 6, -0.5), 0.4});
  for (int k = 0; k < 14; ++k) {
    const Vec3 c(3.5 * u(rng), 0.9 + 2.2 * h(rng), 3.5 * u(rng));
    const Vec3 d(0.8 * u(rng), 0.8 * u(rng), 0.8 * u(rng));
    const double r = 0.1 + 0.3 * h(rng);
    switch (k % 4) {
      case 0:
        add(Sphere{c, r});
        break;
      case 1:  // cylinders
        add(Cone{c, r, c + d, r, k % 8 == 1});
        break;
      case 2:  // cones
        add(Cone{c, r, c + d, 0.0, false});
        break;
      default:  // frustums
        add(Cone{c, r, c + d, 0.5 * r * h(rng), k % 8 == 3});
        break;
    }
  }
  RenderParams rt;
  RenderParams p = config_iv();
  p.aa = 4;
  auto ref = prepare_scene(s, rt);
  auto iv = prepare_scene(s, p);
  ASSERT_TRUE(ref.ok() && iv.ok());
  const PreparedScene& ps = **iv;
  const CameraFrame& cam = ps.camera;
  Stats rs, vs;
  Tracer tracer(**ref, rs);
  SpanShadows shadows(ps, 0.0, vs);
  shadows.set_group_rows(8.0);
  std::vector<double> xs;
  int compared = 0, shadowed = 0;
  for (int k = 0; k <= 4 * cam.height; ++k) {
    const double y = k / 4.0;
    shadows.set_line(y);
    const int row = std::min(k / 4, cam.height - 1);
    for (const int f : ps.scan->cover[row]) {
      const ScanFace& face = ps.scan->faces[f];
      if (ps.prims.prims[face.prim].object != 0 || y < face.ymin || y > face.ymax) continue;
      shadows.begin_span(f, 0.0, static_cast<double>(cam.width));
      ASSERT_FALSE(shadows.uncertain(0.0, cam.width)) << "line " << y << ": an exact test is left";
      xs.clear();
      shadows.breakpoints(xs);
      std::vector<double> probes;
      for (int i = 0; i < 40; ++i) probes.push_back(cam.width * h(rng));
      for (const double x : xs) {
        for (const double dx : {-1e-6, 1e-6}) probes.push_back(x + dx);
      }
      for (const double x : probes) {
        if (!(x > 0 && x < cam.width)) continue;
        const Vec3 dir = cam.direction(x, y);
        const double t =
            (face.offset - glm::dot(face.normal, cam.from)) / glm::dot(face.normal, dir);
        if (!(t > 0)) continue;
        const Vec3 pt = cam.from + t * dir;
        const LightStates st = shadows.states(x);
        for (int light = 0; light < 2; ++light) {
          const bool dark = tracer.transmittance(pt, face.normal, light) == Color(0.0);
          ASSERT_EQ((st.opaque >> light) & 1, dark ? 1u : 0u)
              << "light " << light << " at (" << x << ", " << y << ")";
          ++compared;
          shadowed += dark;
        }
      }
    }
  }
  std::printf("exact curved intervals: %d states compared, %d shadowed\n", compared, shadowed);
  EXPECT_GT(compared, 10000);
  EXPECT_GT(shadowed, 2000);
}

}  // namespace
}  // namespace locus
