// Derived quantities of the scene model (scene.h).
#include "common/scene/scene.h"

#include <cmath>

namespace locus {
namespace {

// SHADING.md "Lights": the SPD suggestion sqrt(L) / (2L) for L lights.
double spd_intensity(size_t lights) {
  if (lights == 0) return 0.0;
  const double l = static_cast<double>(lights);
  return std::sqrt(l) / (2.0 * l);
}

}  // namespace

Color light_emission(const Scene& scene, int light) {
  const Light& l = scene.lights.at(light);
  return l.emission ? *l.emission : Color(spd_intensity(scene.lights.size()));
}

double ambient_intensity(const Scene& scene) {
  // Unchanged when lights carry their own colours (SHADING.md "Lights").
  return scene.ambient ? *scene.ambient : spd_intensity(scene.lights.size());
}

std::vector<bool> csg_operand_mask(const Scene& scene) {
  std::vector<bool> operand(scene.objects.size(), false);
  for (const Object& o : scene.objects) {
    if (const auto* csg = std::get_if<Csg>(&o.shape)) {
      for (int i : {csg->left, csg->right}) {
        if (i >= 0 && static_cast<size_t>(i) < operand.size()) operand[i] = true;
      }
    }
  }
  return operand;
}

}  // namespace locus
