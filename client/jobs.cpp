// The CLI's jobs (client/jobs.h): a scene loaded, sized and checked once
// (prepare_job), then rendered in process or on an embedded local farm,
// or submitted to a farm and followed.
#include "client/jobs.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <thread>

#include "client/farm_client.h"
#include "client/local_farm.h"
#include "client/progress.h"
#include "common/base/cost_map.h"
#include "common/base/log.h"
#include "common/farm/auth.h"
#include "common/farm/band_split.h"
#include "common/farm/movie.h"
#include "common/render.h"
#include "common/scene/animation.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus::cli {

namespace fs = std::filesystem;

int fail(const std::string& message) {
  std::fprintf(stderr, "locus: %s\n", message.c_str());
  return 1;
}

int fail(const Status& status) { return fail(status.message()); }

// "A-B" or "A"; empty: frame 1.
Status parse_frames(const std::string& s, int* first, int* last) {
  if (s.empty()) {
    *first = *last = 1;
    return Status::Ok();
  }
  static const std::regex re("^([0-9]{1,9})(?:-([0-9]{1,9}))?$");
  std::smatch m;
  if (!std::regex_match(s, m, re)) {
    return InvalidArgument("--frames: expected A-B such as 1-24 (or one frame number), got '" + s +
                           "'");
  }
  *first = std::stoi(m[1]);
  *last = m[2].matched ? std::stoi(m[2]) : *first;
  if (*last < *first)
    return InvalidArgument("--frames " + s + ": the last frame comes before the first");
  if (*last - *first + 1 > farm::kMaxFramesPerJob) {
    return InvalidArgument("--frames " + s + ": at most " + std::to_string(farm::kMaxFramesPerJob) +
                           " frames");
  }
  return Status::Ok();
}

namespace {

// Parses "WxH" into the camera's resolution.
bool parse_size(const std::string& s, int* w, int* h) {
  static const std::regex re("^([0-9]{1,6})x([0-9]{1,6})$");
  std::smatch m;
  if (!std::regex_match(s, m, re)) return false;
  *w = std::stoi(m[1]);
  *h = std::stoi(m[2]);
  return *w > 0 && *h > 0;
}

void make_parent_dirs(const std::string& path) {
  std::error_code ec;
  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
}

// --cost-map, checked before anything is rendered: a format write_image
// knows, not -o's file, a frame number field for several frames, and a
// directory that exists (or can be made) and can be written.
Status check_cost_map(const JobArgs& a, int frames) {
  const std::string& path = a.cost_map;
  std::string where = "--cost-map ";
  where.append(path).append(": ");
  if (output_sample_format(path) == SampleFormat::kUnsupported) {
    return InvalidArgument(where + "unsupported image format; use .png, .exr or .tif");
  }
  if (fs::path(path).lexically_normal() == fs::path(a.output).lexically_normal()) {
    return InvalidArgument(where + "the same file as -o; give the cost map a name of its own");
  }
  if (frames > 1 && !has_frame_field(path)) {
    return InvalidArgument(where + std::to_string(frames) +
                           " frames need a frame number field in the file name, e.g. "
                           "cost_####.png");
  }
  make_parent_dirs(path);
  const fs::path parent = fs::path(path).has_parent_path() ? fs::path(path).parent_path() : ".";
  std::error_code ec;
  if (!fs::is_directory(parent, ec) || access(parent.c_str(), W_OK) != 0) {
    return FailedPrecondition(where + "cannot write into the directory " + parent.string());
  }
  return Status::Ok();
}

// A loaded, sized scene and the job around it, ready for either path.
struct PreparedJob {
  Scene scene;
  farm::SubmitRequest request;  // request.scene is filled only for the farm
  double load_seconds = 0;      // load_scene's wall time (Stats::seconds_load)
};

Result<PreparedJob> prepare_job(const JobArgs& a, bool for_farm) {
  PreparedJob job;
  farm::SubmitRequest& r = job.request;
  if (Status s = parse_frames(a.frames, &r.frame_first, &r.frame_last); !s.ok()) return s;
  const int frames = r.frame_last - r.frame_first + 1;
  if (frames > 1 && !has_frame_field(a.output)) {
    return InvalidArgument(
        "-o " + a.output + ": " + std::to_string(frames) +
        " frames need a frame number field in the file name, e.g. shot_####.png");
  }
  const auto load_start = std::chrono::steady_clock::now();
  auto scene = load_scene(a.scene);
  if (!scene.ok()) return scene.status();
  job.load_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();
  job.scene = std::move(*scene);
  if (!a.size.empty()) {
    int w, h;
    if (!parse_size(a.size, &w, &h)) {
      return InvalidArgument("--size: expected WIDTHxHEIGHT such as 640x480, got '" + a.size + "'");
    }
    if (w > kMaxResolution || h > kMaxResolution) {
      return InvalidArgument("--size: " + a.size + " exceeds the limit of " +
                             std::to_string(kMaxResolution) + " pixels per side");
    }
    job.scene.camera.width = w;
    job.scene.camera.height = h;
  }
  r.scene_name = a.scene;
  r.render = a.render;
  r.width = job.scene.camera.width;
  r.height = job.scene.camera.height;
  r.bands = a.bands;
  // The directories of -o are this side's: the coordinator gets the file
  // name alone and writes under its own output root.
  r.output = for_farm ? fs::path(a.output).filename().string() : a.output;
  r.orbit_degrees = a.orbit;
  if (a.bands > r.height) {
    return InvalidArgument("--bands " + std::to_string(a.bands) + ": the frame has only " +
                           std::to_string(r.height) + " rows; a band is at least one row");
  }
  if (!a.movie.empty()) {
    const std::string name = fs::path(a.movie).filename().string();
    if (Status s = farm::check_movie(name, a.fps, a.output); !s.ok()) {
      return InvalidArgument("--movie " + a.movie + ": " + s.message());
    }
    // The farm gets the file name alone, like the frames'.
    r.movie = name;
    r.fps = a.fps > 0 ? a.fps : farm::kDefaultFps;
  }
  if (!a.cost_map.empty()) {
    // Written here (in process, or fetched from a farm by render and
    // submit --wait): checked before anything is rendered.
    if (Status s = check_cost_map(a, frames); !s.ok()) return s;
    // The farm gets the file name alone, like the frames'.
    if (for_farm) r.cost_map = fs::path(a.cost_map).filename().string();
  }
  if (for_farm) r.scene = scene_to_proto(job.scene);
  return job;
}

Status write_stats(const std::string& path, const Stats& stats) {
  if (path.empty()) return Status::Ok();
  std::ofstream f(path);
  f << stats.to_json();
  if (!f) return FailedPrecondition(path + ": cannot write stats file");
  return Status::Ok();
}

// --movie of `locus render --workers 0`: the frames just written, made
// into the movie here, as a farm's coordinator would.
Status make_movie_here(const JobArgs& a, const farm::SubmitRequest& r) {
  farm::MovieInput in;
  const fs::path frames(a.output);
  in.frames_dir = frames.has_parent_path() ? frames.parent_path().string() : ".";
  in.pattern = frames.filename().string();
  in.first = r.frame_first;
  in.last = r.frame_last;
  in.fps = r.fps;
  in.out_path = a.movie;
  make_parent_dirs(a.movie);
  auto made = farm::assemble_movie(in, nullptr);
  if (!made.ok()) return made.status();
  spdlog::info("movie {} written ({} frames at {} fps, {} bytes)", a.movie,
               r.frame_last - r.frame_first + 1, r.fps, *made);
  return Status::Ok();
}

// --workers 0: every frame of `job` (prepare_job's) rendered here,
// through the same frame_scene() the workers use.
int render_in_process(const RenderArgs& a, Result<PreparedJob> job) {
  if (!job.ok()) return fail(job.status());
  auto params = farm::to_render_params(job->request.render, a.threads);
  if (!params.ok()) return fail(params.status());
  params->visibility = *label_value(kVisibilityLabels, a.visibility);  // checked by CLI11
  params->shadows = *label_value(kShadowPassLabels, a.shadows);        // checked by CLI11
  if (Status st = check_render_params(*params); !st.ok()) return fail(st);
  const farm::SubmitRequest& r = job->request;
  Stats total;
  total.seconds_load = job->load_seconds;
  double seconds = 0;
  // Frames that differ only in their camera share one geometry.
  AnimationGeometry geometry(job->scene);
  for (int f = r.frame_first; f <= r.frame_last; ++f) {
    const Camera view = farm::frame_camera(job->scene, r.width, r.height, f, r.frame_first,
                                           r.frame_last, r.orbit_degrees);
    // The last frame takes the job's scene itself: a one-frame render
    // never copies its meshes.
    auto frame = [&] {
      return farm::frame_scene(f == r.frame_last ? std::move(job->scene) : job->scene, r.width,
                               r.height, f, r.frame_first, r.frame_last, r.orbit_degrees);
    };
    CostBuffer cost;
    auto result =
        render_frame(geometry, view, frame, *params, a.job.cost_map.empty() ? nullptr : &cost);
    if (!result.ok()) return fail(result.status());
    const std::string path = frame_path(a.job.output, f);
    make_parent_dirs(path);
    if (Status st = write_image(path, result->pixels); !st.ok()) return fail(st);
    if (!a.job.cost_map.empty()) {
      // Display values (sRGB-tagged): the map is a picture, not radiance.
      const std::string cost_path = frame_path(a.job.cost_map, f);
      if (Status st = write_image(cost_path, cost_map_image(cost), true); !st.ok()) {
        std::string message = "--cost-map: ";
        return fail(message.append(st.message()));
      }
    }
    total += result->stats;
    seconds += result->stats.seconds_prepare + result->stats.seconds_render;
  }
  if (Status st = write_stats(a.stats, total); !st.ok()) return fail(st);
  spdlog::info("rendered {} ({}x{}, {} frame{}) in {:.3f} s -> {}", a.job.scene, r.width, r.height,
               r.frame_last - r.frame_first + 1, r.frame_last > r.frame_first ? "s" : "", seconds,
               a.job.output);
  if (!a.job.movie.empty()) {
    if (Status st = make_movie_here(a.job, r); !st.ok()) return fail(st);
  }
  return 0;
}

// How a job's files are fetched: every written frame (or cost map) of the
// job, each to dest (FarmClient::fetch over gRPC; LocalFarm::fetch in the
// embedded farm's process).
using Fetch = std::function<Result<std::vector<std::string>>(
    const std::string& job_id, const client::FileDest& dest, bool cost_maps)>;

Fetch fetch_by(client::FarmClient& farm) {
  return [&farm](const std::string& job_id, const client::FileDest& dest, bool cost_maps) {
    return farm.fetch(job_id, {}, dest, cost_maps);
  };
}

// Follows a job to its end with a progress display on stderr, then fetches
// its frames to the output pattern, and their cost maps to `cost_map`'s
// (empty: none). Returns the process exit code.
int follow_and_fetch(client::FarmClient& farm, const Fetch& fetch, const farm::JobInfo& submitted,
                     const std::string& output, bool show_progress, farm::JobInfo* final_info,
                     const std::string& cost_map = {}) {
  client::Progress progress(stderr, isatty(STDERR_FILENO) != 0);
  auto done = farm.watch(submitted.job_id, [&](const farm::JobInfo& j) {
    if (show_progress) progress.update(j);
  });
  progress.finish();
  if (!done.ok()) return fail(done.status());
  if (final_info) *final_info = *done;
  if (done->state != farm::JobState::kSucceeded) {
    return fail("job " + done->job_id + " " + farm::job_state_name(done->state) +
                (done->error.empty() ? "" : ": " + done->error));
  }
  auto files = fetch(
      done->job_id, [&](int frame, const std::string&) { return frame_path(output, frame); },
      /*cost_maps=*/false);
  if (!files.ok()) return fail(files.status());
  if (!cost_map.empty()) {
    auto maps = fetch(
        done->job_id, [&](int frame, const std::string&) { return frame_path(cost_map, frame); },
        /*cost_maps=*/true);
    if (!maps.ok()) return fail(maps.status());
  }
  return 0;
}

// The movie job of a render job that follow_and_fetch() saw succeed:
// followed too, and its file fetched to `movie` (the client's path).
int follow_movie(client::FarmClient& farm, const Fetch& fetch, const farm::JobInfo& render,
                 const std::string& movie) {
  if (movie.empty()) return 0;
  if (render.movie_job.empty()) return fail("job " + render.job_id + " has no movie job");
  auto job = farm.job(render.movie_job);
  if (!job.ok()) return fail(job.status());
  std::fprintf(stderr, "locus: job %s makes the movie %s\n", job->job_id.c_str(), movie.c_str());
  make_parent_dirs(movie);
  return follow_and_fetch(farm, fetch, *job, movie, false, nullptr);
}

int render_on_local_farm(const RenderArgs& a, int workers) {
  // Farm mode: --threads is per worker, and a worker is one core unless
  // told otherwise (the farm's parallelism is its workers).
  client::LocalFarmOptions options;
  options.workers = workers;
  options.threads = a.threads_given ? a.threads : 1;
  // The coordinator and workers log to their own places; keep this
  // terminal for the job's progress.
  const auto level = spdlog::get_level();
  spdlog::set_level(spdlog::level::warn);
  const auto start = std::chrono::steady_clock::now();
  auto local = client::LocalFarm::start(options);
  if (!local.ok()) {
    spdlog::set_level(level);
    return fail(local.status());
  }
  // The scene is read, and the job submitted, while the workers load and
  // register. The coordinator counts the registered workers twice at
  // submission: for the default number of bands, which this farm gives
  // itself (it knows how many workers it started), and for whether a cost
  // preview pays (cost_split_pays); where that answer could depend on how
  // many have registered yet, the job waits for them.
  auto job = prepare_job(a.job, true);
  if (!job.ok()) {
    local->reset();
    spdlog::set_level(level);
    return fail(job.status());
  }
  farm::SubmitRequest& request = job->request;
  if (Status fits = client::check_submission_size(request); !fits.ok()) {
    local->reset();
    spdlog::set_level(level);
    // Without --workers, `locus render` chose the farm itself: the scene
    // renders in process, as it would have with --workers 0.
    if (a.workers_given) return fail(fits.message() + ": render it in process (--workers 0)");
    spdlog::warn("{}: rendering in process", fits.message());
    // The scene already read (a large one's load is long); its wire form
    // is not needed.
    job->request.scene = v1::Scene();
    return render_in_process(a, std::move(job));
  }
  if (request.bands == 0) {
    request.bands = farm::default_bands(request.width, request.height,
                                        request.frame_last - request.frame_first + 1, workers,
                                        !request.cost_map.empty());
  }
  if (cost_split_pays(request.bands, 0) != cost_split_pays(request.bands, workers)) {
    if (Status ready = (*local)->wait_for_workers(); !ready.ok()) {
      local->reset();
      spdlog::set_level(level);
      return fail(ready);
    }
  }
  if (!(*local)->dashboard_url().empty()) {
    std::fprintf(stderr, "locus: watch the render at %s\n", (*local)->dashboard_url().c_str());
  }
  farm::Credentials local_creds;
  local_creds.token = (*local)->token();
  client::FarmClient farm((*local)->address(), local_creds);
  auto submitted = (*local)->submit(request);
  Status ready = submitted.ok() ? (*local)->wait_for_workers() : submitted.status();
  if (!ready.ok()) {
    local->reset();
    spdlog::set_level(level);
    return fail(ready);
  }
  farm::JobInfo info;
  // Followed over gRPC (the progress display's stream); the files taken
  // from the coordinator by a call.
  const Fetch fetch = [&local](const std::string& job_id, const client::FileDest& dest,
                               bool cost_maps) { return (*local)->fetch(job_id, dest, cost_maps); };
  int rc = follow_and_fetch(farm, fetch, *submitted, a.job.output, isatty(STDERR_FILENO) != 0,
                            &info, a.job.cost_map);
  if (rc == 0) rc = follow_movie(farm, fetch, info, a.job.movie);
  if (rc != 0) {
    (*local)->keep_logs();
    const std::string logs = (*local)->dir();
    local->reset();
    spdlog::set_level(level);
    std::fprintf(stderr, "locus: the local farm's logs are in %s\n", logs.c_str());
    return rc;
  }
  spdlog::set_level(level);
  if (Status st = write_stats(a.stats, info.stats); !st.ok()) {
    local->reset();
    return fail(st);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("rendered {} ({}x{}, {} frame{}, {} bands each, {} workers) in {:.3f} s -> {}",
               a.job.scene, info.spec.width, info.spec.height, info.spec.frames(),
               info.spec.frames() > 1 ? "s" : "", info.spec.bands, workers, seconds, a.job.output);
  // Every file of the command is written: the farm ends with the process.
  (*local)->exit_process(0);
}

}  // namespace

int run_render(const RenderArgs& a) {
  int workers = a.workers;
  if (workers < 0) workers = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (workers == 0) return render_in_process(a, prepare_job(a.job, false));
  if (a.visibility != RenderArgs{}.visibility || a.shadows != RenderArgs{}.shadows) {
    // A farm job chooses both per frame (auto); the job's settings do not
    // carry a forced choice.
    spdlog::info("--visibility {} --shadows {}: renders in process", a.visibility, a.shadows);
    return render_in_process(a, prepare_job(a.job, false));
  }
  if (!a.workers_given && !client::worker_binary().ok()) {
    spdlog::warn("{}; rendering in process", client::worker_binary().status().message());
    return render_in_process(a, prepare_job(a.job, false));
  }
  return render_on_local_farm(a, workers);
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

int run_submit(const std::string& address, const farm::Credentials& creds, const SubmitArgs& a) {
  // Validated here first: the user sees the scene's problems and nothing
  // reaches the coordinator.
  auto job = prepare_job(a.job, true);
  if (!job.ok()) return fail(job.status());
  job->request.priority = a.priority;
  job->request.frame_order = a.frame_order;
  job->request.require = a.require;
  job->request.after = a.after;
  job->request.notify_url = a.notify_url;
  job->request.band_timeout =
      farm::Millis(static_cast<int64_t>(std::llround(a.band_timeout * 1000)));
  client::FarmClient farm(address, creds);
  auto submitted = farm.submit(job->request);
  if (!submitted.ok()) return fail(submitted.status());
  std::printf("%s\n", submitted->job_id.c_str());
  std::fflush(stdout);
  if (!submitted->movie_job.empty()) {
    std::fprintf(stderr, "locus: job %s makes the movie %s after it\n",
                 submitted->movie_job.c_str(), job->request.movie.c_str());
  }
  if (!a.wait) return 0;
  farm::JobInfo info;
  const Fetch fetch = fetch_by(farm);
  const int rc =
      follow_and_fetch(farm, fetch, *submitted, a.job.output, true, &info, a.job.cost_map);
  return rc != 0 ? rc : follow_movie(farm, fetch, info, a.job.movie);
}

}  // namespace locus::cli
