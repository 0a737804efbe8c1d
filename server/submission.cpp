#include "server/submission.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "common/base/text.h"
#include "common/farm/band_split.h"
#include "common/farm/movie.h"
#include "common/farm/paths.h"
#include "common/scene/animation.h"
#include "common/scene/scene_io.h"

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// The scene within the farm's limits, as the renderer reads it.
Result<Scene> check_scene(const SubmitRequest& r, const std::string& name, const Limits& limits,
                          const std::string& mesh_root) {
  if (r.scene.objects_size() > limits.max_objects) {
    return InvalidArgument(name + ": " + std::to_string(r.scene.objects_size()) +
                           " objects; this farm takes at most " +
                           std::to_string(limits.max_objects) + " (--max-objects)");
  }
  // OBJ files only from the mesh root (none by default: meshes inline);
  // the scene stored for the workers keeps the names as given.
  Result<Scene> scene = scene_from_wire(r.scene, mesh_root, name);
  // The client's scene is bad; a mesh root the coordinator cannot use is
  // its own (FailedPrecondition, as it comes).
  if (!scene.ok() && scene.status().code() == Code::kFailedPrecondition) return scene.status();
  if (!scene.ok()) return Status(Code::kInvalidArgument, scene.status().message());
  if (!scene->has_camera && (r.width == 0 || r.height == 0)) {
    return InvalidArgument(name + ": the scene has no camera resolution; give the size");
  }
  return scene;
}

// The size (0: the scene camera's) and the frames, into `spec`.
Status check_size_and_frames(const SubmitRequest& r, const Scene& scene, const Limits& limits,
                             JobSpec& spec) {
  spec.width = r.width > 0 ? r.width : scene.camera.width;
  spec.height = r.height > 0 ? r.height : scene.camera.height;
  if (r.width < 0 || r.height < 0 || spec.width < 1 || spec.height < 1 ||
      spec.width > limits.max_resolution || spec.height > limits.max_resolution) {
    return InvalidArgument("size " + std::to_string(spec.width) + "x" +
                           std::to_string(spec.height) + ": each side must be 1.." +
                           std::to_string(limits.max_resolution) + " (--max-resolution)");
  }
  spec.frame_first = r.frame_first;
  spec.frame_last = r.frame_last;
  if (r.frame_first < 0 || r.frame_last < r.frame_first) {
    return InvalidArgument("frames " + std::to_string(r.frame_first) + "-" +
                           std::to_string(r.frame_last) + ": expected A-B with 0 <= A <= B");
  }
  if (static_cast<int64_t>(r.frame_last) - r.frame_first + 1 > limits.max_frames) {
    return InvalidArgument("frames " + std::to_string(r.frame_first) + "-" +
                           std::to_string(r.frame_last) + ": at most " +
                           std::to_string(limits.max_frames) + " frames per job (--max-frames)");
  }
  return Status::Ok();
}

// The coordinator writes only under its data directory, so of the client's
// pattern it keeps the file name alone. `what` names the setting in
// messages ("output", "cost map"), `example` is a pattern for it.
Result<std::string> file_pattern(const std::string& pattern, int frames, const std::string& what,
                                 const std::string& example) {
  if (pattern.empty())
    return InvalidArgument(what + ": a pattern such as out/" + example + " is required");
  // Confined: the coordinator writes under its output root only, and says
  // so rather than quietly dropping what would lead elsewhere.
  if (Status s = check_no_parent_refs(pattern, what); !s.ok()) return s;
  const std::string quoted = what + " '" + pattern + "'";
  if (fs::path(pattern).is_absolute()) {
    return InvalidArgument(quoted +
                           ": absolute paths are refused; the coordinator writes each job's "
                           "frames under its output root, give a file name such as " +
                           example);
  }
  const std::string name = fs::path(pattern).filename().string();
  if (name.empty() || name == "." || name == "..") {
    return InvalidArgument(quoted + ": names no file; expected a pattern such as out/" + example);
  }
  if (std::any_of(name.begin(), name.end(),
                  [](unsigned char c) { return c < 0x20 || c == 0x7f; })) {
    return InvalidArgument(what + ": the file name contains control characters");
  }
  const std::string ext = lower(fs::path(name).extension().string());
  if (ext != ".png" && ext != ".exr" && ext != ".tif" && ext != ".tiff") {
    return InvalidArgument(quoted + ": unsupported image type '" + ext +
                           "' (expected .png, .exr, .tif)");
  }
  if (frames > 1 && !has_frame_field(name)) {
    return InvalidArgument(quoted + ": " + std::to_string(frames) +
                           " frames need a frame number field in the file name, e.g. " + example);
  }
  return name;
}

// The cost maps' pattern (docs/cost-map.md "On the farm"): a file name of
// its own beside the frames.
Status check_cost_map(const SubmitRequest& r, JobSpec& spec) {
  if (r.cost_map.empty()) return Status::Ok();
  Result<std::string> name = file_pattern(r.cost_map, spec.frames(), "cost map", "cost_####.png");
  if (!name.ok()) return name.status();
  if (*name == spec.output) {
    return InvalidArgument("cost map '" + r.cost_map +
                           "': the frames' file name; give the cost maps a name of their own");
  }
  spec.cost_map = *name;
  return Status::Ok();
}

// The band count asked for (0: the coordinator's default, chosen later).
Status check_bands(int bands, const JobSpec& spec) {
  const int least = min_bands(spec.width, spec.height, !spec.cost_map.empty());
  if (bands < 0 || bands > spec.height) {
    return InvalidArgument("bands " + std::to_string(bands) + ": expected 1.." +
                           std::to_string(spec.height) + " (a band is at least one row of the " +
                           std::to_string(spec.height) + "-row frame)");
  }
  if (bands > 0 && bands < least) {
    return InvalidArgument("bands " + std::to_string(bands) + ": a " + std::to_string(spec.width) +
                           "x" + std::to_string(spec.height) + " frame needs at least " +
                           std::to_string(least) + " bands so that each fits in one message" +
                           (spec.cost_map.empty() ? "" : " with its cost counts"));
  }
  return Status::Ok();
}

Status check_request_id(const std::string& id) {
  if (id.size() > 128 ||
      std::any_of(id.begin(), id.end(), [](unsigned char c) { return c <= 0x20 || c >= 0x7f; })) {
    return InvalidArgument("request_id: at most 128 printable characters without spaces");
  }
  return Status::Ok();
}

// The longest --band-timeout a job may ask for.
constexpr Millis kMaxBandTimeout = std::chrono::hours(24 * 7);

// Priority, frame order and band timeout.
Status check_scheduling(const SubmitRequest& r, JobSpec& spec) {
  if (r.priority < kMinPriority || r.priority > kMaxPriority) {
    return InvalidArgument("priority " + std::to_string(r.priority) + ": expected " +
                           std::to_string(kMinPriority) + ".." + std::to_string(kMaxPriority));
  }
  spec.priority = r.priority;
  if (!r.frame_order.empty()) {
    auto order = label_value(kFrameOrderLabels, r.frame_order);
    if (!order) {
      return InvalidArgument("frame order '" + r.frame_order.substr(0, 64) + "': expected one of " +
                             label_choices(kFrameOrderLabels));
    }
    spec.frame_order = *order;
  }
  if (r.band_timeout.count() < 0 || r.band_timeout > kMaxBandTimeout) {
    return InvalidArgument("band timeout " + std::to_string(r.band_timeout.count()) +
                           " ms: expected 0 (the coordinator's) up to " +
                           std::to_string(kMaxBandTimeout.count()) + " ms (7 days)");
  }
  spec.band_timeout = r.band_timeout;
  if (Status s = check_tags(r.require, "require"); !s.ok()) return s;
  spec.require = r.require;
  if (r.after.size() > kMaxAfter) {
    return InvalidArgument("after: at most " + std::to_string(kMaxAfter) + " jobs, got " +
                           std::to_string(r.after.size()));
  }
  for (const std::string& id : r.after) {
    if (id.empty() || id.size() > 64) return InvalidArgument("after: a job id is 1..64 characters");
  }
  spec.after = r.after;
  return Status::Ok();
}

// The movie (common/farm/movie.h) and the notification URL's form (which
// URLs the farm allows is the coordinator's --notify-urls).
Status check_movie_and_notify(const SubmitRequest& r, JobSpec& spec) {
  if (Status s = check_movie(r.movie, r.fps, spec.output); !s.ok()) return s;
  if (!r.movie.empty() && r.movie == spec.output) {
    return InvalidArgument("movie " + r.movie + ": the frames' file name; name the movie apart");
  }
  spec.movie = r.movie;
  spec.fps = r.movie.empty() ? 0 : r.fps > 0 ? r.fps : kDefaultFps;
  if (!r.notify_url.empty()) {
    if (auto u = parse_http_url(r.notify_url, "notify URL"); !u.ok()) return u.status();
  }
  spec.notify_url = r.notify_url;
  return Status::Ok();
}

}  // namespace

Result<CheckedSubmission> check_submission(const SubmitRequest& r, const Limits& limits,
                                           const std::string& mesh_root) {
  CheckedSubmission job;
  job.name = r.scene_name.empty() ? "scene" : r.scene_name.substr(0, 256);
  Result<Scene> scene = check_scene(r, job.name, limits, mesh_root);
  if (!scene.ok()) return scene.status();
  job.scene = std::move(*scene);
  JobSpec& spec = job.spec;
  spec.scene_name = job.name;
  if (Status s = check_size_and_frames(r, job.scene, limits, spec); !s.ok()) return s;
  Result<RenderParams> params = to_render_params(r.render, 0);
  if (!params.ok()) return params.status();
  job.params = *params;
  spec.render = from_render_params(*params);  // defaults resolved, as workers will
  if (!std::isfinite(r.orbit_degrees))
    return InvalidArgument("orbit: must be a finite number of degrees");
  spec.orbit_degrees = r.orbit_degrees;
  Result<std::string> pattern = file_pattern(r.output, spec.frames(), "output", "shot_####.png");
  if (!pattern.ok()) return pattern.status();
  spec.output = *pattern;
  // Before the bands: a job's cost counts travel with its pixels.
  if (Status s = check_cost_map(r, spec); !s.ok()) return s;
  if (Status s = check_bands(r.bands, spec); !s.ok()) return s;
  if (Status s = check_request_id(r.request_id); !s.ok()) return s;
  if (Status s = check_scheduling(r, spec); !s.ok()) return s;
  if (Status s = check_movie_and_notify(r, spec); !s.ok()) return s;
  return job;
}

namespace {
// Settings that came later: at their defaults a job keeps the fingerprint
// it had.
std::string scheduling_fingerprint(const JobSpec& spec) {
  std::string out;
  if (spec.priority != kDefaultPriority) out += "|priority " + std::to_string(spec.priority);
  if (spec.frame_order != FrameOrder::kInOrder)
    out += std::string("|order ") + label_name(kFrameOrderLabels, spec.frame_order).data();
  if (spec.band_timeout.count() > 0)
    out += "|band-timeout " + std::to_string(spec.band_timeout.count());
  if (!spec.require.empty()) out += "|require " + words_text(spec.require);
  if (!spec.after.empty()) out += "|after " + words_text(spec.after);
  if (!spec.movie.empty()) out += "|movie " + spec.movie + " " + std::to_string(spec.fps);
  if (!spec.notify_url.empty()) out += "|notify " + spec.notify_url;
  if (!spec.cost_map.empty()) out += "|cost-map " + spec.cost_map;
  return out;
}
}  // namespace

std::string submission_fingerprint(const SubmitRequest& r, const JobSpec& spec) {
  // The tolerance came later: at its default a job keeps the fingerprint
  // it had.
  const std::string tess_tol = spec.render.tess_tol != kDefaultTessTol
                                   ? "|tess-tol " + format_number(spec.render.tess_tol)
                                   : "";
  return content_hash(spec.scene_hash + "|" + spec.render.method + "|" + spec.render.boxes + "|" +
                      std::to_string(spec.render.spp) + "|" + std::to_string(r.width) + "x" +
                      std::to_string(r.height) + "|" + std::to_string(r.frame_first) + "-" +
                      std::to_string(r.frame_last) + "|" + std::to_string(r.bands) + "|" +
                      r.output + "|" + std::to_string(r.orbit_degrees) + tess_tol +
                      scheduling_fingerprint(spec));
}

std::vector<int> cost_band_edges(const CheckedSubmission& job, std::vector<float>* row_costs) {
  const JobSpec& spec = job.spec;
  if (spec.bands <= 1 || job.params.method != Method::kLocal) return {};
  const int middle = spec.frame_first + (spec.frame_last - spec.frame_first) / 2;
  const Scene posed = frame_scene(job.scene, spec.width, spec.height, middle, spec.frame_first,
                                  spec.frame_last, spec.orbit_degrees);
  Result<std::vector<double>> costs = predict_row_costs(posed, job.params);
  if (!costs.ok()) {
    spdlog::warn("{}: no cost prediction ({}); bands of equal height", job.name,
                 costs.status().message());
    return {};
  }
  if (row_costs) row_costs->assign(costs->begin(), costs->end());
  return split_rows_by_cost(*costs, spec.bands);
}

}  // namespace locus::farm

namespace locus::farm {

Result<HttpUrl> parse_http_url(const std::string& url, const std::string& what) {
  std::string shown(1, '\'');  // appended: GCC 12 misreads "'" + string as an overlapping copy
  shown.append(url, 0, 128).append(url.size() > 128 ? "...'" : "'");
  const auto bad = [&](const std::string& why) {
    return InvalidArgument(what + " " + shown + ": " + why +
                           " (expected http://HOST[:PORT]/PATH or https://...)");
  };
  if (url.size() > 2048) return bad("longer than 2048 characters");
  if (std::any_of(url.begin(), url.end(), [](unsigned char c) { return c <= 0x20 || c >= 0x7f; }))
    return bad("spaces or characters outside printable ASCII");
  HttpUrl u;
  size_t at;
  if (url.rfind("http://", 0) == 0) {
    at = 7;
  } else if (url.rfind("https://", 0) == 0) {
    u.https = true;
    u.port = 443;
    at = 8;
  } else {
    return bad("not an http:// or https:// URL");
  }
  const size_t end = url.find_first_of("/?#", at);
  const std::string authority = url.substr(at, end == std::string::npos ? end : end - at);
  if (authority.find('@') != std::string::npos) return bad("user information is not allowed");
  std::string port;
  if (!authority.empty() && authority.front() == '[') {
    const size_t close = authority.find(']');
    if (close == std::string::npos) return bad("an IPv6 address without its ']'");
    u.host = authority.substr(1, close - 1);
    if (u.host.empty() || u.host.find_first_not_of("0123456789abcdefABCDEF:.") != std::string::npos)
      return bad("not an IPv6 address in brackets");
    const std::string rest = authority.substr(close + 1);
    if (!rest.empty()) {
      if (rest.front() != ':') return bad("junk after the IPv6 address");
      port = rest.substr(1);
    }
  } else {
    const size_t colon = authority.find(':');
    u.host = authority.substr(0, colon);
    if (colon != std::string::npos) port = authority.substr(colon + 1);
    if (u.host.empty() || u.host.size() > 253 ||
        u.host.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-") !=
            std::string::npos)
      return bad("no host, or a host that is neither a name nor an address");
  }
  if (!port.empty() || (authority.size() && authority.back() == ':')) {
    if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
        std::stoi(port) < 1 || std::stoi(port) > 65535)
      return bad("the port must be 1..65535");
    u.port = std::stoi(port);
  }
  if (end != std::string::npos && url[end] == '#') return bad("a fragment (#...) is not sent");
  u.path = end == std::string::npos ? "/" : url.substr(end);
  if (u.path.front() == '?') u.path.insert(0, "/");
  if (u.path.find('#') != std::string::npos) return bad("a fragment (#...) is not sent");
  return u;
}

Status check_notify_url(const std::string& url, const std::vector<std::string>& allowed) {
  auto u = parse_http_url(url, "notify URL");
  if (!u.ok()) return u.status();
  const auto lower = [](std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
    return s;
  };
  for (const std::string& entry : allowed) {
    auto a = parse_http_url(entry, "--notify-urls");
    if (!a.ok() || a->https != u->https || a->port != u->port || lower(a->host) != lower(u->host))
      continue;
    // Under the allowed path: the same path, or one below it.
    if (a->path == "/" || u->path == a->path) return Status::Ok();
    if (u->path.rfind(a->path, 0) == 0 &&
        (a->path.back() == '/' || u->path[a->path.size()] == '/' || u->path[a->path.size()] == '?'))
      return Status::Ok();
  }
  return Status(Code::kPermissionDenied,
                "notify URL " + std::string(url, 0, 128) + " is not allowed on this farm" +
                    (allowed.empty() ? " (its coordinator allows none: --notify-urls)"
                                     : " (its coordinator's --notify-urls lists the allowed ones)"));
}

}  // namespace locus::farm
