// locus-band-balance: load imbalance of a frame's bands (issue #9 item 4).
// Renders every band of one frame alone, one thread each, with bands of
// equal height and with bands of equal predicted cost (common/farm/band_split.h),
// and prints each band's CPU seconds (best of --reps) and the imbalance:
// the slowest band's time over the mean. In a farm with as many workers as
// bands, the frame takes as long as its slowest band.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <numeric>

#include "common/farm/band_split.h"
#include "common/scene/scene_io.h"

namespace {
using namespace locus;

std::vector<double> band_seconds(const PreparedScene& ps, const RenderParams& p,
                                 const std::vector<int>& edges, int reps) {
  std::vector<double> t;
  for (size_t b = 0; b + 1 < edges.size(); ++b) {
    double best = 1e300;
    for (int r = 0; r < reps; ++r) {
      best = std::min(best, render_band(ps, Band{edges[b], edges[b + 1]}, p).stats.seconds_render_cpu);
    }
    t.push_back(best);
  }
  return t;
}

void report(const char* name, const std::vector<int>& edges, const std::vector<double>& t) {
  const double mean = std::accumulate(t.begin(), t.end(), 0.0) / static_cast<double>(t.size());
  const double worst = *std::max_element(t.begin(), t.end());
  std::printf("%s edges", name);
  for (int e : edges) std::printf(" %d", e);
  std::printf("\n%s seconds", name);
  for (double s : t) std::printf(" %.4f", s);
  std::printf("\n%s imbalance %.3f (slowest %.4f s, mean %.4f s)\n", name, worst / mean, worst, mean);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Load imbalance of a frame's bands: equal heights against equal predicted cost"};
  std::string scene_path, size = "512x512";
  int bands = 8, aa = 4, reps = 3;
  app.add_option("scene", scene_path, "Scene file")->required();
  app.add_option("--size", size, "WIDTHxHEIGHT");
  app.add_option("--bands", bands, "Bands per frame")->check(CLI::Range(1, 4096));
  app.add_option("--aa", aa, "Sub-scanlines per row")->check(CLI::Range(0, 64));
  app.add_option("--reps", reps, "Runs per band (best is kept)")->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  auto scene = load_scene(scene_path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  if (std::sscanf(size.c_str(), "%dx%d", &scene->camera.width, &scene->camera.height) != 2) {
    std::fprintf(stderr, "--size: expected WIDTHxHEIGHT, got '%s'\n", size.c_str());
    return 1;
  }
  RenderParams p;
  p.method = Method::kLocal;
  p.aa = aa;
  p.threads = 1;
  auto ps = prepare_scene(*scene, p);
  if (!ps.ok()) {
    std::fprintf(stderr, "%s\n", ps.status().message().c_str());
    return 1;
  }
  const int h = scene->camera.height;
  std::vector<int> equal(bands + 1);
  for (int b = 0; b <= bands; ++b) equal[b] = static_cast<int>(static_cast<int64_t>(h) * b / bands);
  auto costs = predict_row_costs(*scene, p);
  if (!costs.ok()) {
    std::fprintf(stderr, "%s\n", costs.status().message().c_str());
    return 1;
  }
  const std::vector<int> cost = split_rows_by_cost(*costs, bands);
  report("equal", equal, band_seconds(**ps, p, equal, reps));
  report("cost", cost, band_seconds(**ps, p, cost, reps));
  return 0;
}
