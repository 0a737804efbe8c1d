// locus: the command-line client. `render` renders in process (--workers 0)
// or on an embedded local farm; `validate` checks a scene; `submit` (these
// three in client/jobs.cpp), `status`, `watch`, `cancel`, `workers` and
// `fetch` talk to a coordinator; `health` asks a coordinator's or a
// worker's health service (probes).
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>

#include "client/farm_client.h"
#include "client/jobs.h"
#include "client/progress.h"
#include "common/base/log.h"
#include "common/farm/auth.h"
#include "common/farm/band_split.h"
#include "common/farm/movie.h"
#include "common/scene/animation.h"
#include "proto/wire/health.h"

namespace {

using namespace locus;
using namespace locus::cli;
namespace fs = std::filesystem;

// ---------------------------------------------------------------- farm commands

void print_job(const farm::JobInfo& j) {
  std::printf("job %s: %s\n", j.job_id.c_str(), farm::job_state_name(j.state));
  std::printf("  owner    %s, priority %d%s\n", j.spec.owner.empty() ? "-" : j.spec.owner.c_str(),
              j.spec.priority,
              j.spec.frame_order == farm::FrameOrder::kInOrder ? "" : ", frames first-middle-last");
  if (j.spec.kind == farm::JobKind::kMovie) {
    std::printf("  movie    %s of the frames of job %s, at %d fps (made by the coordinator)\n",
                j.spec.output.c_str(), j.spec.after.empty() ? "?" : j.spec.after[0].c_str(),
                j.spec.fps);
  } else {
    std::printf("  scene    %s, %dx%d, frames %d-%d, %d bands per frame\n",
                j.spec.scene_name.c_str(), j.spec.width, j.spec.height, j.spec.frame_first,
                j.spec.frame_last, j.spec.bands);
  }
  if (!j.movie_job.empty()) {
    std::printf("  movie    %s at %d fps, by job %s\n", j.spec.movie.c_str(), j.spec.fps,
                j.movie_job.c_str());
  }
  if (!j.spec.notify_url.empty()) std::printf("  notify   %s\n", j.spec.notify_url.c_str());
  if (!j.spec.cost_map.empty()) std::printf("  cost map %s\n", j.spec.cost_map.c_str());
  std::printf("  progress %lld/%lld bands, %d/%d frames written, %s elapsed\n",
              static_cast<long long>(j.bands_done), static_cast<long long>(j.spec.bands_total()),
              j.frames_done, j.spec.frames(), client::format_duration(j.seconds_elapsed).c_str());
  std::printf("  output   %s (fetch with `locus fetch %s DIR`)\n", j.spec.output.c_str(),
              j.job_id.c_str());
  if (!j.error.empty()) std::printf("  error    %s\n", j.error.c_str());
  if (j.results_discarded > 0 || j.speculative_leases > 0) {
    std::printf("  races    %lld speculative leases, %lld late results discarded\n",
                static_cast<long long>(j.speculative_leases),
                static_cast<long long>(j.results_discarded));
  }
  for (const std::string& w : j.quarantined) std::printf("  quarantined worker %s\n", w.c_str());
  std::printf("  account  %.1f band-seconds rendered, %.1f failed, %.1f lost; %.1f CPU seconds\n",
              j.account.done, j.account.failed, j.account.lost, j.stats.seconds_render_cpu);
  if (!j.spec.require.empty())
    std::printf("  requires workers tagged %s\n", farm::words_text(j.spec.require).c_str());
  if (!j.spec.after.empty()) std::printf("  after    %s\n", farm::words_text(j.spec.after).c_str());
  if (!j.waiting.empty()) std::printf("  %s\n", j.waiting.c_str());
  if (j.bands_timed_out > 0) {
    std::printf("  hung     %lld bands taken back by the band timeout (`locus events %s`)\n",
                static_cast<long long>(j.bands_timed_out), j.job_id.c_str());
  }
}

int run_status(const std::string& address, const farm::Credentials& creds,
               const std::string& job_id) {
  client::FarmClient farm(address, creds);
  if (!job_id.empty()) {
    auto j = farm.job(job_id);
    if (!j.ok()) return fail(j.status());
    print_job(*j);
    return 0;
  }
  auto jobs = farm.jobs();
  if (!jobs.ok()) return fail(jobs.status());
  if (jobs->empty()) {
    std::printf("no jobs\n");
    return 0;
  }
  std::printf("%-8s %-10s %-4s %-12s %-13s %-15s %-10s %s\n", "JOB", "STATE", "PRIO", "OWNER",
              "FRAMES", "BANDS", "ELAPSED", "SCENE");
  // Per user, over the jobs the coordinator holds.
  std::map<std::string, std::array<double, 4>> users;
  for (const farm::JobInfo& j : *jobs) {
    auto& u = users[j.spec.owner.empty() ? "-" : j.spec.owner];
    u[0] += j.account.done;
    u[1] += j.account.failed;
    u[2] += j.account.lost;
    u[3] += j.stats.seconds_render_cpu;
  }
  for (const farm::JobInfo& j : *jobs) {
    const std::string frames =
        std::to_string(j.frames_done) + "/" + std::to_string(j.spec.frames());
    const std::string bands =
        std::to_string(j.bands_done) + "/" + std::to_string(j.spec.bands_total());
    std::printf("%-8s %-10s %-4d %-12s %-13s %-15s %-10s %s\n", j.job_id.c_str(),
                farm::job_state_name(j.state), j.spec.priority,
                j.spec.owner.empty() ? "-" : j.spec.owner.c_str(), frames.c_str(), bands.c_str(),
                client::format_duration(j.seconds_elapsed).c_str(),
                j.spec.kind == farm::JobKind::kMovie
                    ? ("movie " + j.spec.output + " of " +
                       (j.spec.after.empty() ? std::string("?") : j.spec.after[0]))
                          .c_str()
                    : j.spec.scene_name.c_str());
  }
  std::printf("\n%-12s %14s %12s %12s %12s\n", "USER", "BAND-SECONDS", "FAILED", "LOST",
              "CPU-SECONDS");
  for (const auto& [user, u] : users) {
    std::printf("%-12s %14.1f %12.1f %12.1f %12.1f\n", user.c_str(), u[0], u[1], u[2], u[3]);
  }
  return 0;
}

int run_watch(const std::string& address, const farm::Credentials& creds,
              const std::string& job_id) {
  client::FarmClient farm(address, creds);
  client::Progress progress(stdout, isatty(STDOUT_FILENO) != 0);
  auto done = farm.watch(job_id, [&](const farm::JobInfo& j) { progress.update(j); });
  progress.finish();
  if (!done.ok()) return fail(done.status());
  if (!done->error.empty()) std::printf("error: %s\n", done->error.c_str());
  return done->state == farm::JobState::kSucceeded ? 0 : 1;
}

int run_cancel(const std::string& address, const farm::Credentials& creds,
               const std::string& job_id) {
  client::FarmClient farm(address, creds);
  auto j = farm.cancel(job_id);
  if (!j.ok()) return fail(j.status());
  std::printf("job %s: %s (%lld/%lld bands done)\n", j->job_id.c_str(),
              farm::job_state_name(j->state), static_cast<long long>(j->bands_done),
              static_cast<long long>(j->spec.bands_total()));
  return 0;
}

// pause, resume, priority: the job's state afterwards.
int print_action(const Result<farm::JobInfo>& j) {
  if (!j.ok()) return fail(j.status());
  std::printf("job %s: %s, priority %d (%lld/%lld bands done, %lld running)\n", j->job_id.c_str(),
              farm::job_state_name(j->state), j->spec.priority,
              static_cast<long long>(j->bands_done), static_cast<long long>(j->spec.bands_total()),
              static_cast<long long>(j->bands_running));
  return 0;
}

std::string format_time(double unix_seconds) {
  const std::time_t t = static_cast<std::time_t>(unix_seconds);
  std::tm tm{};
  localtime_r(&t, &tm);
  char buf[40];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  char out[48];
  std::snprintf(out, sizeof out, "%s.%03d", buf,
                static_cast<int>((unix_seconds - std::floor(unix_seconds)) * 1000));
  return out;
}

struct EventsArgs {
  int frame = -1;  // -1: every frame
  int band = -1;
  bool follow = false;
};

// Prints lines of a job after a cursor (`print_after` prints those after
// `after`, moves it on and says how many came); with `follow`, polls for
// more every 0.5 s until the job has ended and nothing more comes.
int follow_lines(client::FarmClient& farm, const std::string& job_id, bool follow,
                 const std::function<Result<size_t>(int64_t& after)>& print_after) {
  int64_t after = 0;
  for (;;) {
    auto printed = print_after(after);
    if (!printed.ok()) return fail(printed.status());
    std::fflush(stdout);
    if (!follow) return 0;
    auto j = farm.job(job_id);
    if (!j.ok()) return fail(j.status());
    if (farm::is_terminal(j->state) && *printed == 0) return 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

// What workers logged for the job's bands.
int run_logs(const std::string& address, const farm::Credentials& creds, const std::string& job_id,
             const EventsArgs& a) {
  client::FarmClient farm(address, creds);
  return follow_lines(farm, job_id, a.follow, [&](int64_t& after) -> Result<size_t> {
    auto lines = farm.logs(job_id, a.frame, a.band, after);
    if (!lines.ok()) return lines.status();
    for (const farm::BandLogLine& l : *lines) {
      after = l.seq;
      std::printf("frame %d band %d %s: %s\n", l.frame, l.band, l.worker_id.c_str(),
                  l.text.c_str());
    }
    return lines->size();
  });
}

// The job's history.
int run_events(const std::string& address, const farm::Credentials& creds,
               const std::string& job_id, const EventsArgs& a) {
  client::FarmClient farm(address, creds);
  return follow_lines(farm, job_id, a.follow, [&](int64_t& after) -> Result<size_t> {
    auto events = farm.events(job_id, after);
    if (!events.ok()) return events.status();
    for (const farm::HistoryEntry& e : *events) {
      after = e.seq;
      if (a.frame >= 0 && e.frame != a.frame && e.frame != -1) continue;
      if (a.band >= 0 && e.band != a.band) continue;
      std::printf("%s  %s\n", format_time(e.at).c_str(), e.text.c_str());
    }
    return events->size();
  });
}

int run_workers(const std::string& address, const farm::Credentials& creds) {
  client::FarmClient farm(address, creds);
  auto ws = farm.workers();
  if (!ws.ok()) return fail(ws.status());
  if (ws->empty()) {
    std::printf("no workers\n");
    return 0;
  }
  std::printf("%-7s %-24s %-8s %-8s %-22s %-7s %-12s %s\n", "WORKER", "NAME", "THREADS", "STATE",
              "BAND", "BANDS", "SEEN", "TAGS");
  for (const farm::WorkerInfo& w : *ws) {
    const std::string band =
        w.busy ? w.job_id + "/f" + std::to_string(w.frame) + "/b" + std::to_string(w.band) : "-";
    char seen[32];
    std::snprintf(seen, sizeof seen, "%.1f s ago", w.seconds_since_seen);
    const std::string tags = w.tags.empty() ? "-" : farm::words_text(w.tags);
    std::printf("%-7s %-24s %-8d %-8s %-22s %-7lld %-12s %s\n", w.worker_id.c_str(), w.name.c_str(),
                w.threads, farm::worker_state_name(w), band.c_str(),
                static_cast<long long>(w.bands_done), seen, tags.c_str());
  }
  return 0;
}

int run_fetch(const std::string& address, const farm::Credentials& creds, const std::string& job_id,
              const std::string& dir) {
  client::FarmClient farm(address, creds);
  auto j = farm.job(job_id);
  if (!j.ok()) return fail(j.status());
  const auto into_dir = [&](int, const std::string& name) {
    return (fs::path(dir) / name).string();
  };
  auto files = farm.fetch(job_id, {}, into_dir);
  if (!files.ok()) return fail(files.status());
  // And their cost maps, when the job makes them (docs/cost-map.md).
  size_t maps = 0;
  if (!j->spec.cost_map.empty()) {
    auto m = farm.fetch(job_id, {}, into_dir, /*cost_maps=*/true);
    if (!m.ok()) return fail(m.status());
    maps = m->size();
  }
  std::printf("%zu frame%s of job %s in %s", files->size(), files->size() == 1 ? "" : "s",
              job_id.c_str(), dir.c_str());
  if (maps > 0) std::printf(" (with %zu cost map%s)", maps, maps == 1 ? "" : "s");
  if (j->state != farm::JobState::kSucceeded) {
    std::printf(" (job %s: %d of %d frames written so far)", farm::job_state_name(j->state),
                j->frames_done, j->spec.frames());
  }
  std::printf("\n");
  return 0;
}

// Exit status 0 when SERVING (Docker's HEALTHCHECK, scripts), 1 otherwise.
int run_health(const std::string& address, const std::string& service,
               const farm::Credentials& creds) {
  auto serving = rpc::check_health(address, service, creds, farm::Millis(5000));
  if (!serving.ok()) return fail(serving.status());
  std::printf("%s\n", *serving ? "SERVING" : "NOT_SERVING");
  return *serving ? 0 : 1;
}

void add_job_flags(CLI::App* cmd, JobArgs& a) {
  cmd->add_option("scene", a.scene, "Scene file (.nff or .json)")->required();
  cmd->add_option(
         "-o,--output", a.output,
         "Output image or pattern (.png, .exr, .tif); #### becomes the zero-padded frame number")
      ->required();
  cmd->add_option("--size", a.size, "Override the resolution, WIDTHxHEIGHT");
  cmd->add_option("--method", a.render.method, "Rendering method: " + label_choices(kMethodLabels))
      ->check(CLI::IsMember(label_names(kMethodLabels)));
  cmd->add_option("--boxes", a.render.boxes, "Bounding boxes: " + label_choices(kBoxesLabels))
      ->check(CLI::IsMember(label_names(kBoxesLabels)));
  cmd->add_option("--spp", a.render.spp, "raytrace: N x N stratified samples per pixel")
      ->check(CLI::Range(1, kMaxSpp));
  cmd->add_option("--aa", a.render.aa,
                  "local: N sub-scanlines per pixel row (multi-scanning, paper §3.3; default 4); "
                  "0 = point sampling at pixel centres")
      ->check(CLI::Range(0, kMaxAa));
  cmd->add_option("--tess-tol", a.render.tess_tol,
                  "Bezier surfaces: largest screen-space deviation of their triangles from the "
                  "surface, in pixels (default 0.25)");
  cmd->add_option("--frames", a.frames, "Frames A-B of the animation (default 1)");
  cmd->add_option("--orbit", a.orbit,
                  "The camera orbits `at` about `up` by DEG degrees over the frames");
  cmd->add_option("--bands", a.bands, "Bands per frame (default: several per worker)")
      ->check(CLI::Range(1, 1 << 20));
  cmd->add_option("--movie", a.movie,
                  "Also make a movie of the frames once all are written: FILE.mp4 (H.264, "
                  "yuv420p), .webm (VP9) or .gif; the frames must be PNG or TIFF. On a farm the "
                  "coordinator makes it, as a job of its own after this one");
  cmd->add_option("--fps", a.fps, "The movie's frames per second (default 24)")
      ->check(CLI::Range(1, farm::kMaxFps));
  cmd->add_option(
      "--cost-map", a.cost_map,
      "Also write a cost map of each frame (.png, .exr, .tif): each pixel's rays and "
      "shadow-volume tests in false colour, ray-traced spans outlined, a legend "
      "(docs/cost-map.md); #### for several frames, like -o. On a farm the coordinator writes "
      "it beside the frame");
}

// An option whose value is one of a label table's names.
template <class E, size_t N>
CLI::Option* add_choice(CLI::App* cmd, const std::string& name, std::string& value,
                        const Labels<E, N>& labels, const std::string& help) {
  return cmd->add_option(name, value, help)->check(CLI::IsMember(label_names(labels)));
}

std::string default_farm() {
  const char* env = std::getenv("LOCUS_FARM");
  return env && *env ? env : "127.0.0.1:7000";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Locus: scanline rendering with local ray tracing, on a render farm"};
  app.require_subcommand(1);

  RenderArgs ra;
  auto* render = app.add_subcommand("render", "Render a scene (or frames of it) to images");
  add_job_flags(render, ra.job);
  render
      ->add_option("--threads", ra.threads,
                   "Threads (0 = all cores); with workers: threads per worker (default 1)")
      ->check(CLI::Range(0, 1024));
  render
      ->add_option("--workers", ra.workers,
                   "Local worker processes on an embedded farm (default: one per core); 0 renders "
                   "in process")
      ->check(CLI::Range(0, 256));
  render->add_option("--stats", ra.stats, "Write render statistics as JSON");
  add_choice(render, "--visibility", ra.visibility, kVisibilityLabels,
             "local, configuration IV: how visible surfaces are found: scanline (the paper's "
             "pass), rays (an eye ray per sample) or auto (default: rays where the scene is finer "
             "than its pixels; docs/renderer.md). Not auto: renders in process");
  add_choice(render, "--shadows", ra.shadows, kShadowPassLabels,
             "local, configuration IV: the shadows of scanned spans: volumes (the paper's), "
             "rays (no volumes built) or auto (default: rays where the occluders outnumber what "
             "the image resolves; docs/renderer.md \"Shadows by rays\"). Not auto: renders in "
             "process");

  std::string vpath;
  auto* validate = app.add_subcommand("validate", "Check a scene file and list every problem");
  validate->add_option("scene", vpath, "Scene file")->required();

  std::string farm_address = default_farm();
  std::string token_file;
  farm::Credentials creds;
  auto add_farm = [&](CLI::App* cmd) {
    cmd->add_option("--farm", farm_address,
                    "Coordinator address HOST:PORT (default $LOCUS_FARM or 127.0.0.1:7000)");
    cmd->add_option("--token-file", token_file,
                    "File holding your client token (default: $LOCUS_TOKEN)");
    cmd->add_option("--tls-ca", creds.tls_ca, "CA (PEM) that signed the coordinator's certificate");
    cmd->add_option("--tls-cert", creds.tls_cert, "Client certificate (PEM), for mutual TLS");
    cmd->add_option("--tls-key", creds.tls_key, "Client private key (PEM), for mutual TLS");
    cmd->add_flag("--insecure", creds.insecure,
                  "Plaintext to a non-loopback farm (a trusted network only)");
  };
  SubmitArgs sa;
  auto* submit = app.add_subcommand("submit", "Submit a job to a farm; prints its id");
  add_job_flags(submit, sa.job);
  add_farm(submit);
  submit->add_flag("--wait", sa.wait, "Follow the job and fetch its frames to the output pattern");
  submit
      ->add_option("--priority", sa.priority,
                   "0..100, higher first (default 50); equal priorities share the workers "
                   "between users, then between each user's jobs")
      ->check(CLI::Range(farm::kMinPriority, farm::kMaxPriority));
  submit
      ->add_option("--frame-order", sa.frame_order,
                   "Order of the frames' first leases: " + label_choices(farm::kFrameOrderLabels) +
                       " (first, middle and last frames first, to check a shot early)")
      ->check(CLI::IsMember(label_names(farm::kFrameOrderLabels)));
  submit
      ->add_option("--band-timeout", sa.band_timeout,
                   "Seconds a band may stay leased before it is taken back as hung and retried "
                   "elsewhere (default: the coordinator's --band-timeout)")
      ->check(CLI::Range(0.0, 7 * 24 * 3600.0));
  submit->add_option("--require", sa.require,
                     "A worker tag the job needs (repeatable): its bands go only to workers "
                     "started with --tag for each");
  submit
      ->add_option("--after", sa.after,
                   "Job ids (comma-separated or repeated) this job waits for: it starts when "
                   "all have succeeded and fails if one fails or is cancelled")
      ->delimiter(',');
  submit->add_option("--notify-url", sa.notify_url,
                     "POST the job's final status as JSON to this URL when it ends (with --movie, "
                     "when the movie is made), retried with back-off; the coordinator's "
                     "--notify-urls must allow it");

  std::string job_id, dir;
  auto* status = app.add_subcommand("status", "Show one job, or list them all");
  status->add_option("job", job_id, "Job id");
  add_farm(status);
  auto* watch = app.add_subcommand("watch", "Follow a job's progress until it ends");
  watch->add_option("job", job_id, "Job id")->required();
  add_farm(watch);
  auto* cancel = app.add_subcommand("cancel", "Cancel a job");
  cancel->add_option("job", job_id, "Job id")->required();
  add_farm(cancel);
  int priority = farm::kDefaultPriority;
  bool preempt = false;
  auto* prio = app.add_subcommand("priority", "Change a job's priority (at its next lease)");
  prio->add_option("job", job_id, "Job id")->required();
  prio->add_option("priority", priority, "0..100, higher first")
      ->required()
      ->check(CLI::Range(farm::kMinPriority, farm::kMaxPriority));
  prio->add_flag("--preempt", preempt,
                 "Hand the running bands of jobs of lower priority back now (they render again)");
  add_farm(prio);
  auto* pause = app.add_subcommand(
      "pause", "Pause a job: no new leases; bands in flight finish and are kept");
  pause->add_option("job", job_id, "Job id")->required();
  add_farm(pause);
  auto* resume = app.add_subcommand("resume", "Resume a paused job");
  resume->add_option("job", job_id, "Job id")->required();
  add_farm(resume);
  auto* retry = app.add_subcommand(
      "retry", "A failed or cancelled job back in the queue: the bands it lacks, fresh attempts");
  retry->add_option("job", job_id, "Job id")->required();
  add_farm(retry);
  std::string requeue_frames;
  auto* requeue = app.add_subcommand(
      "requeue",
      "Render written frames of a job again (e.g. deleted outputs); each file is replaced only "
      "when its new frame is complete");
  requeue->add_option("job", job_id, "Job id")->required();
  requeue->add_option("--frames", requeue_frames, "A-B or one frame (default: all the job's)");
  add_farm(requeue);
  bool delete_outputs = false;
  auto* del = app.add_subcommand(
      "delete", "Delete a finished job: its record, history and band files (and frames)");
  del->add_option("job", job_id, "Job id")->required();
  del->add_flag("--outputs", delete_outputs, "Its frames too");
  add_farm(del);
  EventsArgs ea;
  // `events` and `logs`: a job, optionally one frame and band, --follow.
  auto add_lines_command = [&](const char* name, const char* help) {
    auto* cmd = app.add_subcommand(name, help);
    cmd->add_option("job", job_id, "Job id")->required();
    cmd->add_option("--frame", ea.frame, "Only this frame's lines");
    cmd->add_option("--band", ea.band, "Only this band's lines");
    cmd->add_flag("--follow", ea.follow, "Keep printing new lines until the job ends");
    add_farm(cmd);
    return cmd;
  };
  auto* events = add_lines_command(
      "events", "A job's history: submission, leases and how they ended, frames, actions");
  std::string worker;
  auto* drain = app.add_subcommand(
      "drain", "Admins: a worker finishes its band, takes no more and exits (maintenance)");
  drain->add_option("worker", worker, "Worker id (w0003) or name (host:pid)")->required();
  add_farm(drain);
  auto* disable = app.add_subcommand(
      "disable", "Admins: keep a worker, by its name, out of every job until `locus enable`");
  disable->add_option("worker", worker, "Worker id (w0003) or name (host:pid)")->required();
  add_farm(disable);
  auto* enable = app.add_subcommand("enable", "Admins: let a disabled worker take bands again");
  enable->add_option("worker", worker, "Worker id or name")->required();
  add_farm(enable);
  auto* logs = add_lines_command(
      "logs", "What workers logged for a job's bands (warnings, errors, timings)");
  auto* workers = app.add_subcommand("workers", "List the farm's workers");
  add_farm(workers);
  auto* fetch = app.add_subcommand("fetch", "Download a job's written frames into a directory");
  fetch->add_option("job", job_id, "Job id")->required();
  fetch->add_option("dir", dir, "Directory")->required();
  add_farm(fetch);
  std::string health_address, health_service;
  auto* health = app.add_subcommand(
      "health", "Ask a coordinator's or worker's gRPC health service; exit 0 when SERVING");
  health->add_option("address", health_address, "HOST:PORT of its --health port (plaintext)")
      ->required();
  health->add_option("--service", health_service,
                     "\"\" (default): ready; \"liveness\": the process runs");
  health->add_option("--tls-ca", creds.tls_ca,
                     "Ask the coordinator's main, TLS port instead, verified with this CA");

  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries what scripts read.
  setup_logging(LogFormat::kText);
  if (render->parsed()) {
    ra.threads_given = render->count("--threads") > 0;
    ra.workers_given = render->count("--workers") > 0;
    return run_render(ra);
  }
  if (validate->parsed()) return run_validate(vpath);
  if (health->parsed()) return run_health(health_address, health_service, creds);
  auto token = farm::load_token(token_file);
  if (!token.ok()) return fail(token.status());
  creds.token = *token;
  if (submit->parsed()) return run_submit(farm_address, creds, sa);
  if (status->parsed()) return run_status(farm_address, creds, job_id);
  if (watch->parsed()) return run_watch(farm_address, creds, job_id);
  if (cancel->parsed()) return run_cancel(farm_address, creds, job_id);
  if (workers->parsed()) return run_workers(farm_address, creds);
  if (prio->parsed()) {
    return print_action(
        client::FarmClient(farm_address, creds).set_priority(job_id, priority, preempt));
  }
  if (pause->parsed()) return print_action(client::FarmClient(farm_address, creds).pause(job_id));
  if (resume->parsed()) return print_action(client::FarmClient(farm_address, creds).resume(job_id));
  if (retry->parsed()) return print_action(client::FarmClient(farm_address, creds).retry(job_id));
  if (requeue->parsed()) {
    std::optional<int> first, last;
    if (!requeue_frames.empty()) {
      int a = 0, b = 0;
      if (Status s = parse_frames(requeue_frames, &a, &b); !s.ok()) return fail(s);
      first = a;
      last = b;
    }
    return print_action(client::FarmClient(farm_address, creds).requeue(job_id, first, last));
  }
  if (events->parsed()) return run_events(farm_address, creds, job_id, ea);
  if (logs->parsed()) return run_logs(farm_address, creds, job_id, ea);
  if (del->parsed()) {
    auto j = client::FarmClient(farm_address, creds).remove(job_id, delete_outputs);
    if (!j.ok()) return fail(j.status());
    std::printf("job %s: deleted%s\n", j->job_id.c_str(), delete_outputs ? " with its frames" : "");
    return 0;
  }
  for (auto [cmd, state] : {std::pair{drain, "draining"}, std::pair{disable, "disabled"},
                            std::pair{enable, "enabled"}}) {
    if (!cmd->parsed()) continue;
    client::FarmClient farm(farm_address, creds);
    auto r = cmd == drain     ? farm.drain_worker(worker)
             : cmd == disable ? farm.disable_worker(worker)
                              : farm.enable_worker(worker);
    if (!r.ok()) return fail(r.status());
    std::printf("worker %s: %s\n", r->c_str(), state);
    return 0;
  }
  if (fetch->parsed()) return run_fetch(farm_address, creds, job_id, dir);
  return 1;
}
