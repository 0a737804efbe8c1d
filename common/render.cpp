#include "common/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <ctime>
#include <cmath>
#include <sstream>
#include <thread>

#include "common/local.h"
#include "common/multiscan.h"
#include "common/prepared.h"
#include "common/raytrace.h"
#include "common/shadow_volume.h"
#include "common/tessellate.h"
#include "common/validate.h"

namespace locus {

CameraFrame::CameraFrame(const Camera& c)
    : from(c.from),
      tan_half(std::tan(glm::radians(c.angle) * 0.5)),
      aspect(static_cast<double>(c.width) / c.height),
      hither(c.hither),
      width(c.width),
      height(c.height) {
  w = glm::normalize(c.at - c.from);
  u = glm::normalize(glm::cross(w, c.up));
  v = glm::cross(u, w);
}

namespace {
// Free-form surfaces become triangles first (METHOD.md §3): everything after
// this sees a mesh.
Scene tessellated(const Scene& s, const RenderParams& params, double* seconds) {
  const auto start = std::chrono::steady_clock::now();
  Scene out = tessellate_scene(s, params.tess_tol);
  *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}
}  // namespace

PreparedScene::PreparedScene(const Scene& s, const RenderParams& params)
    : scene(tessellated(s, params, &seconds_tessellate)),
      camera(scene.camera),
      prims(build_primitives(scene)) {
  bvh_for_rays = params.boxes != Boxes::kNone;
  bvh_for_shadows = params.boxes == Boxes::kEyeShadow;
  if (bvh_for_rays || bvh_for_shadows) bvh = build_bvh(prims.bounds);
  for (int j = 0; j < static_cast<int>(s.lights.size()); ++j) emission.push_back(light_emission(s, j));
  ambient = ambient_intensity(s);
  // Secondary rays start this far off the surface: relative to the scene's
  // size, far above double rounding, far below any feature of SPD scenes.
  Aabb world;
  for (const Aabb& b : prims.bounds) world.extend(b);
  double scale = 1.0;
  if (!world.empty()) scale = std::max({1e-3, max_component(glm::abs(world.lo)), max_component(glm::abs(world.hi))});
  eps = 1e-9 * std::min(scale, 1e7) * 100.0;
  if (params.method == Method::kLocal) scan = std::make_unique<ScanScene>(build_scan_scene(*this, params.aa > 0));
  // The scanline pass finds the shadows of its spans with shadow volumes
  // (paper §3.2 step 2) in configurations II-IV; IV also searches the
  // boxes' volumes for points reached by secondary rays (paper §4.1).
  if (params.method == Method::kLocal) {
    volumes = std::make_shared<const ShadowVolumes>(build_shadow_volumes(*this, bvh_for_shadows));
  }
}

Result<std::shared_ptr<const PreparedScene>> prepare_scene(const Scene& scene,
                                                           const RenderParams& params) {
  if (params.spp < 1 || params.spp > 64) {
    return InvalidArgument("--spp must be between 1 and 64, got " + std::to_string(params.spp));
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
    return InvalidArgument("--aa " + std::to_string(params.aa) +
                           ": multi-scanning belongs to --method local; the ray tracer uses --spp N");
  }
  if (!(params.tess_tol > 0.0 && std::isfinite(params.tess_tol))) {
    return InvalidArgument("--tess-tol must be a positive number of pixels, got " +
                           format_number(params.tess_tol));
  }
  if (scene.camera.width < 1 || scene.camera.height < 1) {
    return InvalidArgument("image size must be positive");
  }
  return std::shared_ptr<const PreparedScene>(std::make_shared<PreparedScene>(scene, params));
}

namespace {
// Rows per unit of multi-scanning work: one sub-scanline in 8n is computed
// twice (at each chunk's first row), and threads still share a band.
constexpr int kMultiscanChunk = 8;
}  // namespace

BandResult render_band(const PreparedScene& ps, const Band& band, const RenderParams& params) {
  const auto start = std::chrono::steady_clock::now();
  const int y0 = std::clamp(band.y0, 0, ps.camera.height);
  const int y1 = std::clamp(band.y1, y0, ps.camera.height);
  BandResult result;
  result.pixels = Image(ps.camera.width, y1 - y0);
  int threads = params.threads > 0 ? params.threads
                                   : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::max(1, std::min(threads, y1 - y0));
  std::vector<Stats> stats(threads);
  std::atomic<int> next{y0};
  std::vector<double> cpu(threads, 0.0);
  auto work = [&](int id) {
    struct CpuClock {
      double& out;
      double start = now();
      static double now() {
        timespec ts{};
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
        return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
      }
      ~CpuClock() { out = now() - start; }
    } clock{cpu[id]};
    if (ps.scan && params.aa > 0) {
      // Multi-scanning: chunks of rows, so that inside a chunk each
      // boundary sub-scanline is computed once (common/multiscan.h).
      for (int y = next.fetch_add(kMultiscanChunk); y < y1; y = next.fetch_add(kMultiscanChunk)) {
        multiscan_rows(ps, params, Band{y0, y1}, y, std::min(y1, y + kMultiscanChunk), result.pixels,
                       stats[id]);
      }
      return;
    }
    for (int y = next++; y < y1; y = next++) {
      if (ps.scan) {
        local_rows(ps, params, Band{y0, y1}, y, result.pixels, stats[id]);
      } else {
        raytrace_rows(ps, params, Band{y0, y1}, y, result.pixels, stats[id]);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(work, i);
  work(0);
  for (auto& t : pool) t.join();
  for (const Stats& s : stats) result.stats += s;
  for (const double c : cpu) result.stats.seconds_render_cpu += c;
  result.stats.geometry_triangles = ps.prims.triangles.size();
  result.stats.shadow_method = !ps.volumes ? "rays" : ps.volumes->search ? "volumes" : "volumes+rays";
  result.stats.seconds_render =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

Result<BandResult> render_image(const Scene& scene, const RenderParams& params) {
  const auto start = std::chrono::steady_clock::now();
  auto prepared = prepare_scene(scene, params);
  if (!prepared.ok()) return prepared.status();
  const double prep = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  BandResult r = render_band(**prepared, Band{0, scene.camera.height}, params);
  r.stats.seconds_prepare = prep;
  r.stats.seconds_tessellate = (*prepared)->seconds_tessellate;
  return r;
}

Stats& Stats::operator+=(const Stats& o) {
  seconds_prepare += o.seconds_prepare;
  seconds_render += o.seconds_render;
  seconds_render_cpu += o.seconds_render_cpu;
  seconds_tessellate += o.seconds_tessellate;
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
  return *this;
}

std::string Stats::to_json() const {
  std::ostringstream o;
  o.precision(9);
  o << "{\n  \"seconds\": {\"prepare\": " << seconds_prepare << ", \"render\": " << seconds_render
    << ", \"render_cpu\": " << seconds_render_cpu
    << ", \"tessellate\": " << seconds_tessellate
    << "},\n  \"geometry\": {\"triangles\": " << geometry_triangles
    << "},\n  \"rays\": {\"eye\": " << rays_eye << ", \"reflected\": " << rays_reflected
    << ", \"refracted\": " << rays_refracted << ", \"shadow\": " << rays_shadow
    << "},\n  \"tests\": {\"ray_object\": " << tests_ray_object
    << ", \"shadow_volume\": " << tests_shadow_volume
    << "},\n  \"pixels\": {\"total\": " << pixels_total << ", \"ray_traced\": " << pixels_ray_traced
    << "},\n  \"spans\": {\"total\": " << spans_total << ", \"ray_traced\": " << spans_ray_traced
    << "},\n  \"shadows\": {\"method\": \"" << shadow_method << "\"}\n}\n";
  return o.str();
}

}  // namespace locus
