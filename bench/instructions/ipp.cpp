// Instructions per pixel (issue #9 item 2): renders a scene in process with
// no image I/O, for callgrind --toggle-collect='locus::render_band*'.
// bench/instructions/run.sh builds and runs it.
#include <cstdio>
#include <cstdlib>
#include "common/render.h"
#include "common/scene/scene_io.h"
using namespace locus;
int main(int argc, char** argv) {
  auto s = load_scene(argv[1]);
  if (!s.ok()) { std::fprintf(stderr, "%s\n", s.status().message().c_str()); return 1; }
  s->camera.width = s->camera.height = argc > 2 ? std::atoi(argv[2]) : 128;
  RenderParams p; p.method = Method::kLocal; p.aa = argc > 3 ? std::atoi(argv[3]) : 4; p.threads = 1;
  auto r = render_image(*s, p);
  std::printf("pixels %llu traced %llu\n", (unsigned long long)r->stats.pixels_total, (unsigned long long)r->stats.pixels_ray_traced);
}
