// locus: the command-line client. `render` and `validate` work in process;
// the farm commands talk to a coordinator.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <regex>

#include "common/render.h"
#include "common/scene_io.h"

namespace {

using namespace locus;

struct RenderArgs {
  std::string scene;
  std::string output;
  std::string size;
  std::string method = "raytrace";
  std::string boxes = "eye+shadow";
  int spp = 1;
  int threads = 0;
  std::string stats;
};

int fail(const std::string& message) {
  std::fprintf(stderr, "locus: %s\n", message.c_str());
  return 1;
}

// Parses "WxH" into the camera's resolution.
bool parse_size(const std::string& s, int* w, int* h) {
  static const std::regex re("^([0-9]{1,6})x([0-9]{1,6})$");
  std::smatch m;
  if (!std::regex_match(s, m, re)) return false;
  *w = std::stoi(m[1]);
  *h = std::stoi(m[2]);
  return *w > 0 && *h > 0;
}

int run_render(const RenderArgs& a) {
  auto scene = load_scene(a.scene);
  if (!scene.ok()) return fail(scene.status().message());
  if (!a.size.empty()) {
    int w, h;
    if (!parse_size(a.size, &w, &h)) {
      return fail("--size: expected WIDTHxHEIGHT such as 640x480, got '" + a.size + "'");
    }
    if (w > kMaxResolution || h > kMaxResolution) {
      return fail("--size: " + a.size + " exceeds the limit of " + std::to_string(kMaxResolution) +
                  " pixels per side");
    }
    scene->camera.width = w;
    scene->camera.height = h;
  }
  RenderParams params;
  params.method = Method::kRaytrace;
  params.boxes = a.boxes == "none" ? Boxes::kNone : (a.boxes == "eye" ? Boxes::kEye : Boxes::kEyeShadow);
  params.spp = a.spp;
  params.threads = a.threads;
  auto result = render_image(*scene, params);
  if (!result.ok()) return fail(result.status().message());
  const Status st = write_image(a.output, result->pixels);
  if (!st.ok()) return fail(st.message());
  if (!a.stats.empty()) {
    std::ofstream f(a.stats);
    f << result->stats.to_json();
    if (!f) return fail(a.stats + ": cannot write stats file");
  }
  spdlog::info("rendered {} ({}x{}) in {:.3f} s -> {}", a.scene, scene->camera.width,
               scene->camera.height, result->stats.seconds_prepare + result->stats.seconds_render,
               a.output);
  return 0;
}

int run_validate(const std::string& path) {
  auto scene = load_scene(path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  std::printf("%s: ok (%zu objects, %zu lights, %dx%d)\n", path.c_str(), scene->objects.size(),
              scene->lights.size(), scene->camera.width, scene->camera.height);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Locus: scanline rendering with local ray tracing, on a render farm"};
  app.require_subcommand(1);

  RenderArgs ra;
  auto* render = app.add_subcommand("render", "Render a scene to an image");
  render->add_option("scene", ra.scene, "Scene file (.nff or .json)")->required();
  render->add_option("-o,--output", ra.output, "Output image (.png, .exr, .tif)")->required();
  render->add_option("--size", ra.size, "Override the resolution, WIDTHxHEIGHT");
  render->add_option("--method", ra.method, "Rendering method")
      ->check(CLI::IsMember({"raytrace"}));
  render->add_option("--boxes", ra.boxes, "Bounding boxes: none, eye, eye+shadow")
      ->check(CLI::IsMember({"none", "eye", "eye+shadow"}));
  render->add_option("--spp", ra.spp, "N: N x N stratified samples per pixel")
      ->check(CLI::Range(1, 64));
  render->add_option("--threads", ra.threads, "Threads (0 = all cores)")->check(CLI::Range(0, 1024));
  render->add_option("--stats", ra.stats, "Write render statistics as JSON");

  std::string vpath;
  auto* validate = app.add_subcommand("validate", "Check a scene file and list every problem");
  validate->add_option("scene", vpath, "Scene file")->required();

  CLI11_PARSE(app, argc, argv);
  if (render->parsed()) return run_render(ra);
  if (validate->parsed()) return run_validate(vpath);
  return 1;
}
