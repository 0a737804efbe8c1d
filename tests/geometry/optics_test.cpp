// Fresnel, total internal reflection, and the transparent-shadow
// transmittance of paper eqs. (2) and (3) against closed forms.
#include <gtest/gtest.h>

#include <cmath>

#include "common/geometry/optics.h"
#include "common/prepare/prepared.h"
#include "common/scene/polyhedron.h"
#include "common/trace/raytrace.h"

namespace locus {
namespace {

TEST(Optics, FresnelNormalIncidence) {
  for (double n : {1.0, 1.33, 1.5, 1.52, 2.4}) {
    const double expected = std::pow((n - 1) / (n + 1), 2);
    EXPECT_NEAR(fresnel(1.0, 1.0, n), expected, 1e-15) << n;
    EXPECT_NEAR(fresnel(1.0, n, 1.0), expected, 1e-15) << n;  // symmetric at normal incidence
  }
}

TEST(Optics, FresnelGrazingAndBrewster) {
  EXPECT_NEAR(fresnel(0.0, 1.0, 1.5), 1.0, 1e-12);
  // At Brewster's angle the p-polarised part vanishes: r = rs^2 / 2.
  const double n = 1.5, theta_b = std::atan(n);
  const double ci = std::cos(theta_b), ct = std::cos(M_PI / 2 - theta_b);
  const double rs = (ci - n * ct) / (ci + n * ct);
  EXPECT_NEAR(fresnel(ci, 1.0, n), 0.5 * rs * rs, 1e-12);
}

TEST(Optics, TotalInternalReflectionBeyondCriticalAngle) {
  const double n = 1.52, critical = std::asin(1.0 / n);
  EXPECT_EQ(fresnel(std::cos(critical + 0.01), n, 1.0), 1.0);
  EXPECT_LT(fresnel(std::cos(critical - 0.01), n, 1.0), 1.0);
  // refract() agrees about where TIR starts.
  const Vec3 nrm(0, 0, 1);
  auto dir_at = [](double angle) { return Vec3(std::sin(angle), 0, -std::cos(angle)); };
  EXPECT_FALSE(refract(dir_at(critical + 0.01), nrm, n).has_value());
  const auto t = refract(dir_at(critical - 0.01), nrm, n);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(glm::length(*t), 1.0, 1e-12);
  // Snell: n1 sin(i) = n2 sin(t).
  EXPECT_NEAR(n * std::sin(critical - 0.01), std::sqrt(t->x * t->x + t->y * t->y), 1e-12);
}

// A light above a glass slab, a point below it: the light crosses the slab
// at normal incidence twice. eq. (3): t = (1 - r)^2 exp(-q d).
struct SlabCase {
  double ior;
  Color q;
  double thickness;
};

Color slab_transmittance(const SlabCase& c, const Vec3& point, Boxes boxes) {
  Scene s;
  s.has_camera = true;
  s.lights.push_back(Light{Vec3(0, 0, 10), std::nullopt});
  Material glass;
  glass.t = 0.9;
  glass.ior = c.ior;
  glass.absorption = c.q;
  s.materials.push_back(glass);
  Object slab;
  slab.shape = make_box(Vec3(-5, -5, 1), Vec3(5, 5, 1 + c.thickness));
  s.objects.push_back(slab);
  RenderParams params;
  params.boxes = boxes;
  const PreparedScene ps(s, params);
  Stats stats;
  Tracer tracer(ps, stats);
  const Color t = tracer.transmittance(point, Vec3(0, 0, 1), 0);
  EXPECT_EQ(stats.rays_shadow, 1u);
  return t;
}

TEST(Optics, GlassSlabShadowMatchesClosedForm) {
  for (const SlabCase& c : {SlabCase{1.5, Color(0.0), 0.5}, SlabCase{1.52, Color(0.4, 1.0, 2.0), 0.7},
                            SlabCase{2.0, Color(0.1), 2.0}}) {
    const double r = std::pow((c.ior - 1) / (c.ior + 1), 2);
    for (Boxes boxes : {Boxes::kNone, Boxes::kEyeShadow}) {
      const Color t = slab_transmittance(c, Vec3(0, 0, 0), boxes);
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(t[k], (1 - r) * (1 - r) * std::exp(-c.q[k] * c.thickness), 1e-12);
      }
    }
  }
}

TEST(Optics, OpaqueOccluderBlocksAndNothingPasses) {
  Scene s;
  s.lights.push_back(Light{Vec3(0, 0, 10), std::nullopt});
  s.materials.push_back(Material{});  // opaque
  Object blocker;
  blocker.shape = Sphere{Vec3(0, 0, 5), 1.0};
  s.objects.push_back(blocker);
  const PreparedScene ps(s, RenderParams{});
  Stats stats;
  Tracer tracer(ps, stats);
  EXPECT_EQ(tracer.transmittance(Vec3(0, 0, 0), Vec3(0, 0, 1), 0), Color(0.0));
  EXPECT_EQ(tracer.transmittance(Vec3(3, 0, 0), Vec3(0, 0, 1), 0), Color(1.0));
  // An occluder beyond the light does not shadow.
  EXPECT_EQ(tracer.transmittance(Vec3(0, 0, 20), Vec3(0, 0, -1), 0), Color(1.0));
}

TEST(Optics, ObliqueCrossingBeyondCriticalAngleIsDark) {
  // A glass wedge above the point: the segment from the point to the light
  // enters its flat bottom at normal incidence and leaves through a top face
  // tilted 60 degrees, beyond the critical angle of 41.8 degrees: r_b = 1,
  // so t_pj = 0 (the dark cores of paper Fig. 8a). Tilted 30 degrees, light
  // passes with (1 - r_a)(1 - r_b).
  for (double tilt_deg : {60.0, 30.0}) {
    Scene s;
    s.lights.push_back(Light{Vec3(0, 0, 20), std::nullopt});
    Material glass;
    glass.t = 1.0;
    glass.ior = 1.5;
    s.materials.push_back(glass);
    const double rise = 6 * std::tan(tilt_deg * M_PI / 180);
    const auto hull = make_hull({Vec3(-3, -3, -2), Vec3(3, -3, -2), Vec3(3, 3, -2), Vec3(-3, 3, -2),
                                 Vec3(-3, -3, 0.5), Vec3(3, -3, 0.5 + rise),
                                 Vec3(3, 3, 0.5 + rise), Vec3(-3, 3, 0.5)});
    ASSERT_TRUE(hull.has_value());
    Object o;
    o.shape = *hull;
    s.objects.push_back(o);
    const PreparedScene ps(s, RenderParams{});
    Stats stats;
    Tracer tracer(ps, stats);
    const Color t = tracer.transmittance(Vec3(0, 0, -20), Vec3(0, 0, 1), 0);
    if (tilt_deg > 41.9) {
      EXPECT_EQ(t, Color(0.0));
    } else {
      const double r_top = 0.04;  // ((1.5 - 1) / (1.5 + 1))^2
      const double r_bottom = fresnel(std::cos(tilt_deg * M_PI / 180), 1.5, 1.0);
      EXPECT_NEAR(t.x, (1 - r_top) * (1 - r_bottom), 1e-12);
    }
  }
}

}  // namespace
}  // namespace locus
