// Scenes and settings shared by the shadow-volume tests
// (shadow_volume_test.cpp, shadow_points_test.cpp).
#pragma once

#include "common/render.h"
#include "common/scene/polyhedron.h"
#include "common/scene/scene.h"
#include "tests/render_compare.h"

namespace locus {

// Configuration IV: the local method with boxes for eye rays and shadows.
inline RenderParams config_iv() {
  RenderParams p;
  p.method = Method::kLocal;
  p.boxes = Boxes::kEyeShadow;
  p.threads = 2;
  return p;
}

inline Object box_object(const Vec3& lo, const Vec3& hi, int material = 0) {
  Object o;
  o.shape = make_box(lo, hi);
  o.material = material;
  return o;
}

// A floor under `light`, seen from above at an angle (96 x 72).
inline Scene floor_scene(const Vec3& light) {
  Scene s = testing_util::camera_scene(Vec3(0, 6, 9), Vec3(0, 0, 0), 50, 96, 72);
  s.lights = {Light{light, std::nullopt}};
  s.objects.push_back(
      testing_util::quad(Vec3(-8, 0, 8), Vec3(8, 0, 8), Vec3(8, 0, -8), Vec3(-8, 0, -8), 0));
  return s;
}

}  // namespace locus
