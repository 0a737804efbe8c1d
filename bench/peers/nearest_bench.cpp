// locus-nearest-bench: the ray kernel's parts timed alone, on one scene's
// eye rays (one per pixel centre, as `--method raytrace --spp 1` casts them),
// one thread, CPU time per ray (docs/renderer.md, "The ray kernel against
// Embree", session 27). Each round times, in turn:
//   raygen   building the eye ray only (subtracted from the lines below);
//   nearest  Tracer::nearest (the walk, the tests, the nearest's bookkeeping);
//   trace    Tracer::trace (nearest, then shading with its shadow and
//            secondary rays);
//   leaf     leaf_nearest on the scene's first leaf copy alone, in a loop
//            (the test's throughput, no walk; "-" where the scene has none).
// Prints the best of --rounds for each. With bench/peers/kernel.py --probes'
// one-primitive scenes it takes a hit apart: nearest on a hit minus nearest
// on a miss is the walk's and the test's share of a hit.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>

#include "common/base/cpu_time.h"
#include "common/geometry/leaf_prims.h"
#include "common/prepare/prepared.h"
#include "common/scene/scene_io.h"
#include "common/trace/raytrace.h"

namespace {

using namespace locus;

// Seconds of CPU for fn(ray) over every pixel centre; `sink` keeps the
// compiler from dropping the work.
template <class Fn>
double time_rays(const CameraFrame& cam, Fn&& fn, double& sink) {
  const double t0 = thread_cpu_seconds();
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Ray ray{cam.from, cam.direction(x + 0.5, y + 0.5)};
      sink += fn(ray);
    }
  }
  return thread_cpu_seconds() - t0;
}

int run(const std::string& path, int size, int rounds) {
  Result<Scene> scene = load_scene(path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  scene->camera.width = scene->camera.height = size;
  RenderParams params;
  params.method = Method::kRaytrace;
  params.threads = 1;
  auto prepared = prepare_scene(*scene, params);
  if (!prepared.ok()) {
    std::fprintf(stderr, "%s\n", prepared.status().message().c_str());
    return 1;
  }
  const PreparedScene& ps = **prepared;
  const CameraFrame& cam = ps.camera;
  Stats stats;
  Tracer tracer(ps, stats);
  const LeafPrim* leaf = nullptr;
  for (const LeafPrim& lp : ps.leaf_prims) {
    if (lp.kind != LeafKind::kOther) {
      leaf = &lp;
      break;
    }
  }
  const double inf = std::numeric_limits<double>::infinity();
  double best[4] = {inf, inf, inf, inf};
  double sink = 0;
  auto nearest = [&](const Ray& ray) {
    const auto hit = tracer.nearest(ray, cam.hither, inf);
    return hit ? hit->t : 0.0;
  };
  auto trace = [&](const Ray& ray) { return tracer.trace(ray, cam.hither, 1, 1.0, nullptr).x; };
  auto alone = [&](const Ray& ray) {
    Crossing c;
    return leaf_nearest(*leaf, ray, cam.hither, inf, &c) ? c.t : 0.0;
  };
  for (int r = 0; r < rounds; ++r) {
    // The order turns from round to round: the first loop of a round ran
    // slower than the others (caches, predictors).
    for (int k = 0; k < 4; ++k) {
      const int part = (k + r) % 4;
      double t = inf;
      if (part == 0)
        t = time_rays(
            cam, [](const Ray& ray) { return ray.dir.x; }, sink);
      if (part == 1) t = time_rays(cam, nearest, sink);
      if (part == 2) t = time_rays(cam, trace, sink);
      if (part == 3 && leaf) t = time_rays(cam, alone, sink);
      best[part] = std::min(best[part], t);
    }
  }
  for (int part = 1; part < 4; ++part) best[part] -= best[0];
  const double rays = static_cast<double>(cam.width) * cam.height;
  std::printf("scene %s, %dx%d, best of %d rounds, ns per ray (checksum %g)\n", path.c_str(), size,
              size, rounds, sink);
  std::printf("raygen  %6.1f\n", best[0] / rays * 1e9);
  std::printf("nearest %6.1f\n", best[1] / rays * 1e9);
  std::printf("trace   %6.1f\n", best[2] / rays * 1e9);
  if (leaf) {
    std::printf("leaf    %6.1f\n", best[3] / rays * 1e9);
  } else {
    std::printf("leaf         -\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-nearest-bench: the ray kernel's parts timed alone on a scene's eye rays"};
  std::string scene;
  int size = 1024, rounds = 5;
  app.add_option("scene", scene, "Scene file (.nff or .json)")->required();
  app.add_option("--size", size, "Image size (square)")->check(CLI::Range(1, 8192));
  app.add_option("--rounds", rounds, "Best of this many rounds")->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  return run(scene, size, rounds);
}
