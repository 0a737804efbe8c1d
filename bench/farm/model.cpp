// locus-farm-model: the farm's efficiency at 8, 64, 512 and 4,096 workers
// for scene (d), from measured figures (issue #25 item 7; docs/farm.md "The
// model, from the measurements"). bench/farm/targets.sh measures the inputs
// in the same run and passes them as "key value" files:
//   coordinator_cpu_us_per_band      scale.sh, 1,000 workers (a band's CPU)
//   round_trip_ms                    scale.sh, 10 workers (workers / bands a second)
//   bytes_per_pixel_png8_deflate     locus-wire-bytes, (d) at the frame size
//   check_ns_per_pixel_png8_deflate  locus-wire-bytes (check_band on arrival)
//   png_join_ns_per_pixel            locus-wire-bytes (png_from_bands)
//   render_ns_per_pixel              locus-wire-bytes (one core, (d), --aa default)
// The model: an animation of --frames frames split by default_bands (the
// job's default split). Each worker, one core, renders its bands and pays
// the round trip per band; the frames the workers could make then ask the
// coordinator for CPU (per band and per pixel), the link for the bands'
// bytes and the disk for them twice (records, then frames). Efficiency is
// the share of the workers' frame rate the scarcest of those can carry,
// times the workers' own share of time spent rendering; the limit is the
// resource that sets it.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "common/farm/types.h"

namespace {

std::map<std::string, double> read_figures(const std::vector<std::string>& files, bool& ok) {
  std::map<std::string, double> v;
  for (const std::string& path : files) {
    std::ifstream in(path);
    if (!in) {
      std::fprintf(stderr, "%s: cannot read\n", path.c_str());
      ok = false;
      continue;
    }
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream words(line);
      std::string key;
      double value = 0;
      if (words >> key >> value) v[key] = value;
    }
  }
  return v;
}

struct Point {
  int workers = 0;
  double frames_per_s = 0;  // what the workers could render
  double cpu_s_per_s = 0;   // the coordinator's CPU they ask for
  double link_bytes_s = 0;  // results on the link
  double disk_bytes_s = 0;  // records, then frames
  double efficiency = 0;
  std::string limit;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The farm's modelled efficiency from measured figures (docs/farm.md)"};
  std::vector<std::string> files;
  int frames = 240;
  double cores = 2, link_gbps = 10, disk_mb_s = 1000;
  app.add_option("figures", files, "\"key value\" files with the measured inputs")->required();
  app.add_option("--frames", frames, "frames of the animation");
  app.add_option("--coordinator-cores", cores, "cores the coordinator has");
  app.add_option("--link-gbps", link_gbps, "the coordinator's link, Gb/s");
  app.add_option("--disk-mb-s", disk_mb_s, "the data directory's disk, MB/s of writes");
  CLI11_PARSE(app, argc, argv);
  bool ok = true;
  const auto v = read_figures(files, ok);
  for (const char* key :
       {"coordinator_cpu_us_per_band", "round_trip_ms", "bytes_per_pixel_png8_deflate",
        "check_ns_per_pixel_png8_deflate", "png_join_ns_per_pixel", "render_ns_per_pixel"}) {
    if (!v.count(key)) {
      std::fprintf(stderr, "missing figure: %s\n", key);
      ok = false;
    }
  }
  if (!ok) return 2;
  const double band_s = v.at("coordinator_cpu_us_per_band") * 1e-6;
  const double round_trip_s = v.at("round_trip_ms") * 1e-3;
  const double pixel_s =
      (v.at("check_ns_per_pixel_png8_deflate") + v.at("png_join_ns_per_pixel")) * 1e-9;
  const double bytes_px = v.at("bytes_per_pixel_png8_deflate");
  const double render_px_s = v.at("render_ns_per_pixel") * 1e-9;
  std::printf(
      "| size | workers | bands a frame | frames/s wanted | coordinator CPU wanted | "
      "link | disk | efficiency | limit |\n|---|---:|---:|---:|---|---|---|---:|---|\n");
  for (const auto& [w, h, label] :
       {std::tuple{1920, 1080, "1080p"}, std::tuple{3840, 2160, "4K"}}) {
    for (int workers : {8, 64, 512, 4096}) {
      const double pixels = static_cast<double>(w) * h;
      const int bands = locus::farm::default_bands(w, h, frames, workers);
      Point p;
      p.workers = workers;
      const double frame_s = pixels * render_px_s + bands * round_trip_s;  // one core
      p.frames_per_s = workers / frame_s;
      p.cpu_s_per_s = p.frames_per_s * (bands * band_s + pixels * pixel_s);
      p.link_bytes_s = p.frames_per_s * pixels * bytes_px;
      p.disk_bytes_s = 2 * p.link_bytes_s;
      const double rendering = pixels * render_px_s / frame_s;
      const std::vector<std::pair<double, std::string>> shares = {
          {cores / p.cpu_s_per_s, "the coordinator's CPU"},
          {link_gbps * 1e9 / 8 / p.link_bytes_s, "the link"},
          {disk_mb_s * 1e6 / p.disk_bytes_s, "the disk"}};
      const auto scarcest = std::min_element(shares.begin(), shares.end());
      p.efficiency = std::min(1.0, scarcest->first) * rendering;
      p.limit = scarcest->first < 1 ? scarcest->second : "none (the workers' round trips)";
      std::printf(
          "| %s | %d | %d | %.1f | %.2f s/s (%.0f%% of %g cores) | %.1f MB/s | %.1f MB/s | "
          "%.1f%% | %s |\n",
          label, workers, bands, p.frames_per_s, p.cpu_s_per_s, 100 * p.cpu_s_per_s / cores, cores,
          p.link_bytes_s / 1e6, p.disk_bytes_s / 1e6, 100 * p.efficiency, p.limit.c_str());
      std::fprintf(stderr, "model_efficiency_%s_%d %.4f\n", label, workers, p.efficiency);
    }
  }
  return 0;
}
