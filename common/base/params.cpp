#include "common/base/params.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "common/base/text.h"

namespace locus {

Status check_render_params(const RenderParams& params) {
  if (params.spp < 1 || params.spp > kMaxSpp) {
    return InvalidArgument("--spp must be between 1 and " + std::to_string(kMaxSpp) + ", got " +
                           std::to_string(params.spp));
  }
  if (params.aa < 0 || params.aa > kMaxAa) {
    return InvalidArgument("--aa must be between 0 and " + std::to_string(kMaxAa) + ", got " +
                           std::to_string(params.aa));
  }
  if (params.method == Method::kLocal && params.spp != 1) {
    return InvalidArgument("--spp " + std::to_string(params.spp) +
                           ": the local method anti-aliases by multi-scanning; use --aa N");
  }
  if (params.method == Method::kRaytrace && params.aa != 0) {
    return InvalidArgument(
        "--aa " + std::to_string(params.aa) +
        ": multi-scanning belongs to --method local; the ray tracer uses --spp N");
  }
  // Configuration IV's own choices (issue #27), each named in the error.
  if (!configuration_iv(params)) {
    std::string flag;
    if (params.visibility != Visibility::kAuto) {
      flag = "--visibility " + std::string(label_name(kVisibilityLabels, params.visibility));
    } else if (params.shadows != ShadowPass::kAuto) {
      flag = "--shadows " + std::string(label_name(kShadowPassLabels, params.shadows));
    }
    if (!flag.empty()) {
      return InvalidArgument(flag + ": only for --method local --boxes eye+shadow (configuration IV)");
    }
  }
  if (!(params.tess_tol > 0.0 && std::isfinite(params.tess_tol))) {
    return InvalidArgument("--tess-tol must be a positive number of pixels, got " +
                           format_number(params.tess_tol));
  }
  return Status::Ok();
}

Stats& Stats::operator+=(const Stats& o) {
  seconds_prepare += o.seconds_prepare;
  seconds_render += o.seconds_render;
  seconds_render_cpu += o.seconds_render_cpu;
  seconds_tessellate += o.seconds_tessellate;
  seconds_load += o.seconds_load;
  geometry_triangles = std::max(geometry_triangles, o.geometry_triangles);
  rays_eye += o.rays_eye;
  rays_reflected += o.rays_reflected;
  rays_refracted += o.rays_refracted;
  rays_shadow += o.rays_shadow;
  tests_ray_object += o.tests_ray_object;
  tests_shadow_volume += o.tests_shadow_volume;
  pixels_total += o.pixels_total;
  pixels_ray_traced += o.pixels_ray_traced;
  spans_total += o.spans_total;
  spans_ray_traced += o.spans_ray_traced;
  if (!o.shadow_method.empty()) shadow_method = o.shadow_method;
  if (!o.visibility.empty()) visibility = o.visibility;
  return *this;
}

std::string Stats::to_json() const {
  std::ostringstream o;
  o.precision(9);
  o << "{\n  \"seconds\": {\"prepare\": " << seconds_prepare << ", \"render\": " << seconds_render
    << ", \"render_cpu\": " << seconds_render_cpu << ", \"tessellate\": " << seconds_tessellate
    << ", \"load\": " << seconds_load
    << "},\n  \"geometry\": {\"triangles\": " << geometry_triangles
    << "},\n  \"rays\": {\"eye\": " << rays_eye << ", \"reflected\": " << rays_reflected
    << ", \"refracted\": " << rays_refracted << ", \"shadow\": " << rays_shadow
    << "},\n  \"tests\": {\"ray_object\": " << tests_ray_object
    << ", \"shadow_volume\": " << tests_shadow_volume
    << "},\n  \"pixels\": {\"total\": " << pixels_total << ", \"ray_traced\": " << pixels_ray_traced
    << "},\n  \"spans\": {\"total\": " << spans_total << ", \"ray_traced\": " << spans_ray_traced
    << "},\n  \"shadows\": {\"method\": \"" << shadow_method
    << "\"},\n  \"visibility\": {\"method\": \"" << visibility << "\"}\n}\n";
  return o.str();
}

}  // namespace locus
