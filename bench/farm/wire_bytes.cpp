// locus-wire-bytes: bytes per pixel of a band's result on the wire (issue
// #25 item 4), today's floats against the encoding of each output format
// (common/farm/band_codec.h). Each scene is rendered band by band as a
// worker renders (BandRenderer, the job's default split), and each band's
// CompleteBandRequest is serialized as the worker sends it: ByteSizeLong of
// the message, ids, stats and all, over the frame's pixels. Prints a
// Markdown table (bench/results/farm-wire.md), and what writing a PNG frame
// costs the coordinator: encoded by OpenImageIO from the stitched floats, or
// joined from the bands' png8+deflate streams (png_from_bands).
// The check on arrival (check_band, what the coordinator does to a result)
// is timed apart from a full decode.
//   locus-wire-bytes [--size 256x256] [--workers 2] [--figures FILE] [SCENE|DIR ...]
// --figures writes the averages as "key value" lines (bench/farm/targets.sh).
// Without scenes: scenes/paper/*.json and ../shared/spd/def/*.nff.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include "common/base/exr.h"
#include "common/base/image.h"
#include "common/farm/band_codec.h"
#include "common/farm/band_split.h"
#include "common/scene/scene_io.h"
#include "proto/wire/rpc.h"
#include "worker/band_renderer.h"

namespace {
using namespace locus;
using namespace locus::farm;
namespace fs = std::filesystem;

double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The jobs measured: today's floats, and each output format's encoding.
struct Column {
  const char* title;
  BandEncoding encoding;
};
constexpr Column kColumns[] = {{"float32 (today)", BandEncoding::kFloat32},
                               {"PNG: rgb8+zstd", BandEncoding::kRgb8Zstd},
                               {"TIFF: rgb16+zstd", BandEncoding::kRgb16Zstd},
                               {"EXR: float32+zstd", BandEncoding::kFloat32Zstd},
                               {"PNG: png8+deflate", BandEncoding::kPng8Deflate},
                               {"EXR: exr+zip", BandEncoding::kExrZip}};
constexpr size_t kN = std::size(kColumns);

struct Row {
  std::string scene;
  std::string group;  // "paper" or "SPD"
  int bands = 0;
  double render_s = 0;
  double bytes_per_pixel[kN] = {};
  double encode_ms[kN] = {};  // per frame: all its bands
  double decode_ms[kN] = {};
  double check_ms[kN] = {};  // check_band: the coordinator's check on arrival
  double png_encode_ms = 0;  // the frame's PNG, written by write_image
  double png_join_ms = 0;    // the frame's PNG, joined from png8+deflate bands and written
  double exr_encode_ms = 0;  // the frame's EXR, written by write_image
  double exr_join_ms = 0;    // the frame's EXR, written from exr+zip bands' blocks
};

// ids as long as the coordinator's (a worker id, "<job>-<counter>" leases).
constexpr const char* kWorkerId = "w-3f9c2a7e51d04b88";
constexpr const char* kLeaseId = "j0007-1c4e9a-000123";

Result<Row> measure(const std::string& path, const std::string& group, int width, int height,
                    int workers) {
  auto scene = load_scene(path);
  if (!scene.ok()) return scene.status();
  BandRenderer renderer(0);
  const std::string hash = "bench";
  if (Status s = renderer.add_scene(hash, scene_to_proto(*scene), path); !s.ok()) return s;
  Row row;
  row.scene = fs::path(path).stem().string();
  row.group = group;
  row.bands = default_bands(width, height, 1, workers);
  // The coordinator's split of an EXR job (align_band_edges), for every
  // column: where it can, each band holds whole blocks.
  const std::vector<int> edges = align_band_edges(height, row.bands, {});
  const double pixels = static_cast<double>(width) * height;
  Image frame(width, height);
  std::vector<EncodedBand> deflated, zipped;
  std::vector<int> y0s;
  for (int b = 0; b < row.bands; ++b) {
    BandLease lease;
    lease.lease_id = kLeaseId;
    lease.scene_hash = hash;
    lease.frame = lease.frame_first = lease.frame_last = 1;
    lease.band = b;
    const Band rows = band_rows(height, row.bands, edges, b);
    lease.y0 = rows.y0;
    lease.y1 = rows.y1;
    lease.width = width;
    lease.height = height;
    const double t0 = now_s();
    auto out = renderer.render(lease);  // floats, as for a float32 lease
    if (!out.ok()) return out.status();
    row.render_s += now_s() - t0;
    std::copy(out->rgb.begin(), out->rgb.end(), frame.pixel(0, rows.y0));
    out->worker_id = kWorkerId;
    out->lease_id = kLeaseId;
    for (size_t c = 0; c < kN; ++c) {
      BandOutput o = *out;
      BandEncoding e = kColumns[c].encoding;
      // As Scheduler::make_lease leases it: exr+zip for a band that holds
      // a whole block of the frame's EXR, float32+zstd otherwise.
      if (e == BandEncoding::kExrZip && !holds_exr_block(rows.y0, rows.y1, height))
        e = BandEncoding::kFloat32Zstd;
      if (e != BandEncoding::kFloat32) {
        // What BandRenderer::render does for a lease of this encoding.
        const double e0 = now_s();
        auto enc = encode_band(e, width, rows.y1 - rows.y0, o.rgb, rows.y0, height);
        row.encode_ms[c] += (now_s() - e0) * 1e3;
        if (!enc.ok()) return enc.status();
        const double d0 = now_s();
        auto dec = decode_band(*enc);
        row.decode_ms[c] += (now_s() - d0) * 1e3;
        if (!dec.ok()) return dec.status();
        const double k0 = now_s();
        if (Status s = check_band(*enc); !s.ok()) return s;
        row.check_ms[c] += (now_s() - k0) * 1e3;
        if (e == BandEncoding::kPng8Deflate) deflated.push_back(*enc);
        if (e == BandEncoding::kExrZip) {
          zipped.push_back(*enc);
          y0s.push_back(rows.y0);
        }
        o.encoded = std::move(*enc);
        o.rgb = {};
      }
      row.bytes_per_pixel[c] +=
          static_cast<double>(rpc::ToProto(std::move(o)).ByteSizeLong()) / pixels;
    }
  }
  // The frame's file on the coordinator, both ways (the file's bytes
  // written, not synced).
  const fs::path dir = fs::temp_directory_path() / "locus-wire-bytes";
  fs::create_directories(dir);
  const double w0 = now_s();
  if (Status s = write_image((dir / "encoded.png").string(), frame); !s.ok()) return s;
  const double w1 = now_s();
  auto png = png_from_bands(width, height, deflated);
  if (!png.ok()) return png.status();
  std::ofstream(dir / "joined.png", std::ios::binary) << *png;
  const double w2 = now_s();
  row.png_encode_ms = (w1 - w0) * 1e3;
  row.png_join_ms = (w2 - w1) * 1e3;
  const double x0 = now_s();
  if (Status s = write_image((dir / "encoded.exr").string(), frame); !s.ok()) return s;
  const double x1 = now_s();
  row.exr_encode_ms = (x1 - x0) * 1e3;
  // Only where every band came as exr+zip; otherwise the coordinator
  // stitches and encodes, as in the row above.
  row.exr_join_ms = row.exr_encode_ms;
  if (static_cast<int>(zipped.size()) == row.bands) {
    auto blocks = exr_blocks_from_bands(width, height, y0s, zipped);
    if (!blocks.ok()) return blocks.status();
    if (Status s = write_exr_blocks((dir / "joined.exr").string(), width, height, blocks->blocks);
        !s.ok())
      return s;
    row.exr_join_ms = (now_s() - x1) * 1e3;
  }
  fs::remove_all(dir);
  return row;
}

std::vector<std::pair<std::string, std::string>> scene_files(const std::vector<std::string>& args) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const std::string& a : args) {
    const std::string group = a.find("spd") != std::string::npos ? "SPD" : "paper";
    if (!fs::is_directory(a)) {
      out.emplace_back(a, group);
      continue;
    }
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(a)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".json" || ext == ".nff") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    for (const std::string& f : files) out.emplace_back(f, group);
  }
  return out;
}

void print_average(const char* label, const std::vector<Row>& rows, const std::string& group) {
  double sum[kN] = {};
  int n = 0;
  for (const Row& r : rows) {
    if (!group.empty() && r.group != group) continue;
    for (size_t c = 0; c < kN; ++c) sum[c] += r.bytes_per_pixel[c];
    ++n;
  }
  if (n == 0) return;
  std::printf("| **%s** (%d scenes) | | |", label, n);
  for (size_t c = 0; c < kN; ++c) std::printf(" **%.3f** |", sum[c] / n);
  std::printf(" %.1fx | %.1fx |\n", sum[0] / sum[1], sum[0] / sum[3]);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Bytes per pixel of band results on the wire, floats against encodings"};
  std::string size = "256x256";
  int workers = 2;
  std::string figures;
  std::vector<std::string> scenes;
  app.add_option("--size", size, "WIDTHxHEIGHT of every scene");
  app.add_option("--workers", workers, "workers the default band split is made for");
  app.add_option("--figures", figures, "write the averages here as \"key value\" lines");
  app.add_option("scenes", scenes, "scene files or directories of them");
  CLI11_PARSE(app, argc, argv);
  int width = 0, height = 0;
  if (std::sscanf(size.c_str(), "%dx%d", &width, &height) != 2 || width < 1 || height < 1) {
    std::fprintf(stderr, "--size: expected WIDTHxHEIGHT, got '%s'\n", size.c_str());
    return 2;
  }
  if (scenes.empty()) {
    scenes = {LOCUS_SOURCE_DIR "/scenes/paper", LOCUS_SOURCE_DIR "/../shared/spd/def"};
  }
  spdlog::set_level(spdlog::level::err);  // the table alone on stdout

  std::vector<Row> rows;
  for (const auto& [path, group] : scene_files(scenes)) {
    auto r = measure(path, group, width, height, workers);
    if (!r.ok()) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), r.status().message().c_str());
      return 1;
    }
    std::fprintf(stderr, "%s: %d bands, rendered in %.2f s\n", path.c_str(), r->bands, r->render_s);
    rows.push_back(std::move(*r));
  }

  std::printf(
      "Bytes per pixel of CompleteBandRequest (serialized), %dx%d, %d bands a frame "
      "(default split for %d workers), configuration IV (local, eye+shadow, aa %d).\n\n",
      width, height, rows.empty() ? 0 : rows.front().bands, workers, kDefaultAa);
  std::printf("| scene | set | render s |");
  for (const Column& c : kColumns) std::printf(" %s |", c.title);
  std::printf(" PNG smaller | EXR smaller |\n|---|---|---:|");
  for (size_t c = 0; c < kN; ++c) std::printf("---:|");
  std::printf("---:|---:|\n");
  for (const Row& r : rows) {
    std::printf("| %s | %s | %.2f |", r.scene.c_str(), r.group.c_str(), r.render_s);
    for (size_t c = 0; c < kN; ++c) std::printf(" %.3f |", r.bytes_per_pixel[c]);
    std::printf(" %.1fx | %.1fx |\n", r.bytes_per_pixel[0] / r.bytes_per_pixel[1],
                r.bytes_per_pixel[0] / r.bytes_per_pixel[3]);
  }
  print_average("average, paper", rows, "paper");
  print_average("average, SPD", rows, "SPD");
  print_average("average, all", rows, "");

  std::printf(
      "\nEncoding and decoding time per frame (all its bands), milliseconds, averaged "
      "over the scenes:\n\n| encoding | encode ms | decode ms | check on arrival ms |\n"
      "|---|---:|---:|---:|\n");
  double check_ns[kN] = {};  // a pixel, averaged
  for (size_t c = 1; c < kN; ++c) {
    double enc = 0, dec = 0, chk = 0;
    for (const Row& r : rows) {
      enc += r.encode_ms[c];
      dec += r.decode_ms[c];
      chk += r.check_ms[c];
    }
    const double n = std::max<size_t>(rows.size(), 1);
    check_ns[c] = chk / n * 1e6 / (static_cast<double>(width) * height);
    std::printf("| %s | %.2f | %.2f | %.2f |\n",
                std::string(label_name(kBandEncodingLabels, kColumns[c].encoding)).c_str(), enc / n,
                dec / n, chk / n);
  }
  double encoded = 0, joined = 0, exr_encoded = 0, exr_joined = 0;
  for (const Row& r : rows) {
    encoded += r.png_encode_ms;
    joined += r.png_join_ms;
    exr_encoded += r.exr_encode_ms;
    exr_joined += r.exr_join_ms;
  }
  const double n = std::max<size_t>(rows.size(), 1);
  std::printf(
      "\nA PNG frame written by the coordinator, milliseconds, averaged over the scenes "
      "(ns a pixel):\n\n| how | ms a frame | ns a pixel |\n|---|---:|---:|\n"
      "| encoded from the stitched floats (write_image, zlib level %d) | %.2f | %.1f |\n"
      "| joined from the bands' png8+deflate streams (png_from_bands) | %.2f | %.1f |\n",
      kPngLevel, encoded / n, encoded / n * 1e6 / (static_cast<double>(width) * height), joined / n,
      joined / n * 1e6 / (static_cast<double>(width) * height));
  std::printf(
      "\nAn EXR frame written by the coordinator, milliseconds, averaged over the scenes "
      "(ns a pixel):\n\n| how | ms a frame | ns a pixel |\n|---|---:|---:|\n"
      "| encoded from the stitched floats (write_image: write_exr, its blocks on every core) | "
      "%.2f | %.1f "
      "|\n| written from the bands' blocks (exr_blocks_from_bands, write_exr_blocks; encoded as "
      "above where a band holds no whole block) | %.2f | %.1f |\n",
      exr_encoded / n, exr_encoded / n * 1e6 / (static_cast<double>(width) * height),
      exr_joined / n, exr_joined / n * 1e6 / (static_cast<double>(width) * height));
  if (!figures.empty()) {
    std::ofstream f(figures);
    double sum[kN] = {};
    for (const Row& r : rows) {
      for (size_t c = 0; c < kN; ++c) sum[c] += r.bytes_per_pixel[c];
    }
    const char* keys[kN] = {"float32",      "rgb8_zstd",    "rgb16_zstd",
                            "float32_zstd", "png8_deflate", "exr_zip"};
    f << "scenes " << rows.size() << "\n";
    for (size_t c = 0; c < kN; ++c) {
      f << "bytes_per_pixel_" << keys[c] << " " << sum[c] / n << "\n";
      if (c > 0) f << "check_ns_per_pixel_" << keys[c] << " " << check_ns[c] << "\n";
    }
    double render = 0;
    for (const Row& r : rows) render += r.render_s;
    f << "render_ns_per_pixel " << render / n * 1e9 / (static_cast<double>(width) * height)
      << "\n";
    f << "png_join_ns_per_pixel " << joined / n * 1e6 / (static_cast<double>(width) * height)
      << "\n";
    if (!f) {
      std::fprintf(stderr, "--figures %s: cannot write\n", figures.c_str());
      return 1;
    }
  }
  return 0;
}
