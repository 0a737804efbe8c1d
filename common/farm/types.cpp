#include "common/farm/types.h"

#include <openssl/evp.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <utility>

#include "common/scene/animation.h"
#include "common/scene/validate.h"

namespace locus::farm {

Result<RenderParams> to_render_params(const RenderSettings& s, int threads) {
  // Only the translation from the wire's names and "unset" values; the
  // ranges and the method/anti-aliasing rules are check_render_params()'s.
  const RenderSettings defaults;
  const auto method = label_value(kMethodLabels, s.method.empty() ? defaults.method : s.method);
  if (!method) {
    return InvalidArgument("--method '" + s.method + "' is unknown; use " +
                           label_choices(kMethodLabels));
  }
  const auto boxes = label_value(kBoxesLabels, s.boxes.empty() ? defaults.boxes : s.boxes);
  if (!boxes) {
    return InvalidArgument("--boxes '" + s.boxes + "' is unknown; use " +
                           label_choices(kBoxesLabels));
  }
  RenderParams p;
  p.method = *method;
  p.boxes = *boxes;
  p.spp = s.spp == 0 ? 1 : s.spp;
  p.aa = s.aa != -1 ? s.aa : (p.method == Method::kLocal ? kDefaultAa : 0);
  p.tess_tol = s.tess_tol;
  p.threads = threads;
  if (Status st = check_render_params(p); !st.ok()) return st;
  return p;
}

RenderSettings from_render_params(const RenderParams& p) {
  RenderSettings s;
  s.method = label_name(kMethodLabels, p.method);
  s.boxes = label_name(kBoxesLabels, p.boxes);
  s.spp = p.spp;
  s.aa = p.aa;
  s.tess_tol = p.tess_tol;
  return s;
}

Band band_rows(int height, int bands, int index) {
  // 64-bit products: height * index overflows int for tall frames cut finely.
  const auto at = [&](int i) { return static_cast<int>(static_cast<int64_t>(height) * i / bands); };
  return Band{at(index), at(index + 1)};
}

Band band_rows(int height, int bands, const std::vector<int>& edges, int index) {
  if (static_cast<int>(edges.size()) == bands + 1) return Band{edges[index], edges[index + 1]};
  return band_rows(height, bands, index);
}

Band band_rows(const JobSpec& spec, int index) {
  return band_rows(spec.height, spec.bands, spec.band_edges, index);
}

Scene frame_scene(Scene base, int width, int height, int frame, int frame_first,
                  int frame_last, double orbit_degrees) {
  base.camera.width = width;
  base.camera.height = height;
  return scene_at_frame(std::move(base), frame, Orbit{orbit_degrees, frame_first, frame_last});
}

Camera frame_camera(const Scene& base, int width, int height, int frame, int frame_first,
                    int frame_last, double orbit_degrees) {
  // The camera and its keys are all that scene_at_frame reads for it.
  Scene view;
  view.camera = base.camera;
  view.has_camera = base.has_camera;
  view.animation.interpolation = base.animation.interpolation;
  view.animation.camera = base.animation.camera;
  return frame_scene(std::move(view), width, height, frame, frame_first, frame_last, orbit_degrees)
      .camera;
}

std::string band_edges_text(const std::vector<int>& edges) {
  std::string out;
  for (size_t i = 0; i < edges.size(); ++i) {
    if (i) out += ' ';
    out += std::to_string(edges[i]);
  }
  return out;
}

Result<std::vector<int>> band_edges_from_text(const std::string& text, int height, int bands) {
  std::vector<int> edges;
  std::istringstream in(text);
  long long v;
  while (in >> v) {
    if (v < 0 || v > height)
      return InvalidArgument("band edges: " + std::to_string(v) + " is outside 0.." +
                             std::to_string(height));
    edges.push_back(static_cast<int>(v));
  }
  if (!in.eof()) return InvalidArgument("band edges: not a list of integers: '" + text + "'");
  if (edges.empty()) return edges;
  bool ok =
      static_cast<int>(edges.size()) == bands + 1 && edges.front() == 0 && edges.back() == height;
  for (size_t i = 1; ok && i < edges.size(); ++i) ok = edges[i] > edges[i - 1];
  if (!ok) {
    return InvalidArgument("band edges: expected " + std::to_string(bands + 1) +
                           " increasing rows from 0 to " + std::to_string(height) + ", got '" +
                           text + "'");
  }
  return edges;
}

int min_bands(int width, int height, bool cost_counts) {
  const int64_t frame_bytes =
      static_cast<int64_t>(width) * height * (3 * 4 + (cost_counts ? kCostCountBytes : 0));
  return static_cast<int>(std::max<int64_t>(1, (frame_bytes + kMaxBandBytes - 1) / kMaxBandBytes));
}

int default_bands(int width, int height, int frames, int workers, bool cost_counts) {
  // 16 bands per worker (at least 2 workers' worth, as workers may join
  // later) spread over the frames: rows differ in cost by orders of
  // magnitude (sky against glass), so many small bands keep the last band's
  // tail short, while a band costs well under a millisecond of overhead
  // (bench/results/farm.md). On 2 workers a frame gets 32 bands: 1.8x the
  // speed of 1 worker where 16 bands gave 1.5x.
  const int64_t target = 16 * static_cast<int64_t>(std::max(workers, 2));
  const int64_t per_frame = (target + frames - 1) / std::max(frames, 1);
  const int64_t n = std::max<int64_t>(per_frame, min_bands(width, height, cost_counts));
  return static_cast<int>(std::clamp<int64_t>(n, 1, std::max(height, 1)));
}

Status check_tags(const std::vector<std::string>& tags, const std::string& what) {
  if (tags.size() > kMaxTags) {
    return InvalidArgument(what + ": at most " + std::to_string(kMaxTags) + " tags, got " +
                           std::to_string(tags.size()));
  }
  for (const std::string& t : tags) {
    const bool ok = !t.empty() && t.size() <= 64 && std::all_of(t.begin(), t.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
    });
    if (!ok) {
      return InvalidArgument(what + " '" + t.substr(0, 64) +
                             "': a tag is 1..64 letters, digits, '_', '-' or '.'");
    }
  }
  return Status::Ok();
}

std::string words_text(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : " ") + w;
  return out;
}

std::vector<std::string> words_from_text(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

std::string content_hash(std::string_view bytes) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_Digest(bytes.data(), bytes.size(), md, &len, EVP_sha256(), nullptr);
  std::string hex;
  hex.reserve(len * 2);
  char buf[3];
  for (unsigned int i = 0; i < len; ++i) {
    std::snprintf(buf, sizeof buf, "%02x", md[i]);
    hex += buf;
  }
  return hex;
}

FrameReady frame_ready(const std::string& job_id, const JobSpec& spec, int frame) {
  FrameReady f;
  f.job_id = job_id;
  f.frame = frame;
  f.file_name = frame_path(spec.output, frame);
  f.width = spec.width;
  f.height = spec.height;
  f.bands = spec.bands;
  f.band_edges = spec.band_edges;
  if (!spec.cost_map.empty()) f.cost_file_name = frame_path(spec.cost_map, frame);
  return f;
}

}  // namespace locus::farm
