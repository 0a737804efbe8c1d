// Stability: scenes built to break the ray-traced parts (eye rays inside
// bounding polyhedra, reflection, refraction, silhouettes found by
// bisection). tests/stability/README.md lists each case, its expectation
// and its bounds.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/stability/stability.h"

namespace locus {
namespace stability {
namespace {

// A checkerboard floor of n x n quads of materials m0 and m1 (sharp edges
// for mirrors and glass to show).
void add_checkerboard(Scene& s, int n, double half, int m0, int m1, double height = 0) {
  const double step = 2 * half / n;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x0 = -half + i * step, z0 = -half + j * step;
      s.objects.push_back(quad(Vec3(x0, height, z0 + step), Vec3(x0 + step, height, z0 + step),
                               Vec3(x0 + step, height, z0), Vec3(x0, height, z0), (i + j) % 2 ? m1 : m0));
    }
  }
}

// The eye inside a glass sphere (ior 1.5), 0.75 of its radius off its
// centre, looking perpendicular to that offset: every eye ray starts in the
// glass; near the image centre rays meet the sphere at 48.6 degrees, beyond
// the critical angle (41.8), and are reflected back inside (TIR) before
// they leave; to the left they leave refracted. The room is seen through
// it, bent. The sphere's bounding polyhedron holds the eye, so the local
// method traces every pixel (docs/local.md); its image must still be the
// ray tracer's.
TEST(Stability, EyeInsideGlassSphere) {
  Scene s = camera_scene(Vec3(0.75, 1.3, 1.2), Vec3(0.75, 0.9, -3), 60, 64, 64);
  // No Ks: a ray tree without reflected branches (TIR still reflects), so
  // that the spp 16 reference stays quick.
  Material g = glass(1.5, 0.9);
  g.ks = 0;
  s.materials = {diffuse(Color(0.85)), diffuse(Color(0.25)), diffuse(Color(0.9, 0.3, 0.2)), g};
  s.lights = {Light{Vec3(2, 5, 3), std::nullopt}};
  add_checkerboard(s, 8, 4, 0, 1);
  s.objects.push_back(sphere(Vec3(0, 1.3, 1.2), 1.0, 3));
  s.objects.push_back(box(Vec3(-1, 0, -2.5), Vec3(0.2, 1.2, -1.5), 2));
  s.objects.push_back(sphere(Vec3(1.5, 0.5, -1.5), 0.5, 2));
  auto ps = prepare_scene(s, params(Method::kLocal, Boxes::kEyeShadow, 0, 1));
  ASSERT_TRUE(ps.ok());
  EXPECT_TRUE((*ps)->scan->trace_everything);
  check_case(s, Bounds{}, "eye inside glass sphere");
}

// Rays grazing spheres: a large diffuse sphere lit from the eye's
// direction (its terminator coincides with its silhouette, N.L -> 0 where
// the eye rays graze it), a mirror sphere whose grazing reflections show
// the checkerboard, a glass sphere (Fresnel reflectance -> 1 at its rim),
// and a sphere whose shadow rays graze a second sphere (the light, the
// occluder's rim and the floor points of the shadow boundary in line). A
// third light lies 0.05 above the floor, 8 away: its shadow rays from the
// floor run within a degree of the floor's plane (shadow acne would show
// as speckles) and graze the spheres' bottoms.
TEST(Stability, RaysGrazingASphere) {
  Scene s = camera_scene(Vec3(0, 1.5, 8), Vec3(0, 0.9, 0), 32, 64, 64);
  s.materials = {diffuse(Color(0.85)), diffuse(Color(0.25)), diffuse(Color(0.9, 0.3, 0.2)), mirror(0.9),
                 glass(1.5, 0.9)};
  s.lights = {Light{Vec3(0, 1.5, 8.01), std::nullopt}, Light{Vec3(-4, 2.5, 1), std::nullopt},
              Light{Vec3(6, 0.05, -5), std::nullopt}};
  add_checkerboard(s, 8, 4, 0, 1);
  s.objects.push_back(sphere(Vec3(-1.3, 1.0, 0), 1.0, 2));
  s.objects.push_back(sphere(Vec3(1.2, 0.8, 0.3), 0.8, 3));
  s.objects.push_back(sphere(Vec3(0.1, 0.45, 1.6), 0.45, 4));
  // Occluder whose rim the second light's rays to the floor graze.
  s.objects.push_back(sphere(Vec3(-2.5, 2.0, 1.5), 0.3, 2));
  check_case(s, Bounds{}, "rays grazing a sphere");
}

// Total internal reflection at grazing angles: a glass slab seen almost
// edge-on (rays enter its top face at 85-89 degrees, refract to just under
// the critical angle and meet the side faces beyond it), a glass triangular
// prism and a dense glass sphere (ior 2.4) whose rim rays reflect inside.
// The TIR branch replaces the refracted ray by a reflected one of the same
// weight (docs/renderer.md); nothing may be NaN, and every mode agrees.
TEST(Stability, TotalInternalReflectionAtGrazingAngles) {
  Scene s = camera_scene(Vec3(0, 0.62, 6), Vec3(0, 0.45, 0), 36, 64, 64);
  s.materials = {diffuse(Color(0.85)), diffuse(Color(0.25)), diffuse(Color(0.9, 0.3, 0.2)),
                 glass(1.5, 0.9), glass(2.4, 0.9)};
  s.lights = {Light{Vec3(2, 5, 4), std::nullopt}};
  add_checkerboard(s, 8, 4, 0, 1);
  s.objects.push_back(box(Vec3(-2.2, 0.01, -1.5), Vec3(0.3, 0.6, 1.5), 3));
  s.objects.push_back(object(make_prism(3, 0.55, Vec3(0.9, 0.01, -0.6), Vec3(0.9, 1.4, -0.6), 30), 3));
  s.objects.push_back(sphere(Vec3(1.4, 0.5, 1.0), 0.49, 4));
  s.objects.push_back(box(Vec3(-1.0, 0.0, -3), Vec3(0.5, 1.5, -2.5), 2));
  Bounds b;
  // Seen through the slab at grazing angles, the floor's edges and the
  // wall's become horizontal lines thinner than a pixel. Multi-scanning
  // samples them on its sub-scanlines only (1/4 px apart): one thinner than
  // that is over- or under-counted on its row (docs/multiscan.md, "features
  // thinner than the sample spacing"). That raises the RMSE over the image,
  // not the per-pixel bound.
  b.aa_rms = 0.02;
  check_case(s, b, "TIR at grazing angles");
}

// Spheres smaller than a pixel: 60 spheres of 0.05 to 0.6 pixel across in
// front of a wall. Point sampling sees a sphere only where a pixel centre
// falls on it (aliasing, not a defect: the point-sampled modes are held to
// configuration I, not to the reference). Multi-scanning finds a sphere
// where a sub-scanline crosses its bounding polyhedron's span (docs/
// multiscan.md): one narrower than the sub-scanline spacing (1/4 px) may
// fall between two and be lost, at most its area, pi (1/8)^2 ~ 0.05 px.
TEST(Stability, SpheresSmallerThanAPixel) {
  Scene s = camera_scene(Vec3(0, 0, 10), Vec3(0, 0, 0), 30, 64, 64);
  s.materials = {diffuse(Color(0.15)), diffuse(Color(1.0, 0.9, 0.6))};
  s.lights = {Light{Vec3(0, 2, 12), std::nullopt}};
  s.objects.push_back(quad(Vec3(-5, -5, -1), Vec3(5, -5, -1), Vec3(5, 5, -1), Vec3(-5, 5, -1), 0));
  // One pixel is 2 * 10 * tan(15 deg) / 64 = 0.0837 units at depth 10.
  const double px = 2 * 10 * std::tan(glm::radians(15.0)) / 64;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> pos(-2.4, 2.4), dia(0.05, 0.6);
  double want_area = 0;
  for (int k = 0; k < 60; ++k) {
    const double d = dia(rng);
    s.objects.push_back(sphere(Vec3(pos(rng), pos(rng), 0), 0.5 * d * px, 1));
    want_area += M_PI * 0.25 * d * d;
  }
  Bounds b;
  b.point_aliasing = true;
  // A lost sphere's pixel is off by its area times the contrast (~0.9):
  // at most 0.6 px across -> 0.28 px^2, but it is lost only if under 1/4
  // px across (0.05 px^2); a found one is measured on 1 to 3 sub-scanlines
  // with the trapezoid weights, off by at most a quarter of its chord.
  b.aa_tol = 0.06;
  b.aa_rms = 0.01;
  const CaseResult r = check_case(s, b, "spheres smaller than a pixel");
  // The total brightness the spheres add over the wall, against the
  // reference's, in pixel areas of contrast.
  auto excess = [&](const Image& img) {
    double sum = 0;
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) sum += img.pixel(x, y)[2];
    }
    return sum;
  };
  const double ref = excess(r.mode("ref16").img), aa = excess(r.mode("IV-aa4").img);
  std::printf("[spheres smaller than a pixel] 60 spheres, %.2f px^2 in all; blue sum ref16 %.3f, "
              "aa4 %.3f (diff %.3f)\n", want_area, ref, aa, aa - ref);
  // The contrast of a sphere over the wall in blue is at most 0.6: lost
  // area below 0.05 px^2 per sphere lost, found ones measured to 30%.
  EXPECT_LT(std::abs(aa - ref), 0.3 * want_area * 0.6);
}

}  // namespace
}  // namespace stability
}  // namespace locus
