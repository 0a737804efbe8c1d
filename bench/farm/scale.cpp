// locus-farm-scale: the coordinator under many workers (issue #25; run by
// bench/farm/scale.sh, and small by CTest farm_scale_quick).
//
// N simulated workers live in this process. Each is a real gRPC client of
// the real coordinator with a connection of its own (gRPC's callback API,
// so that a thousand of them need no thousand threads here): it registers,
// long-polls GetTask, fetches the scene once, heartbeats while it holds a
// band and returns the band after a delay (0: the dispatch ceiling; or
// drawn from a log-normal distribution like real band times) with the
// pixels a worker would send. The frame is rendered once, before the
// clock starts, through the worker's own BandRenderer; each lease gets its
// rows of it, so the harness does not render while it measures.
//
// Some workers misbehave on purpose: --die workers drop their connection
// after their first lease (a killed host), --stall workers keep it and go
// silent (a hung host), --late workers return every band after its lease
// has lapsed without heartbeating (refused, the band leased again).
//
// Prints "key value" lines: bands/s, dispatch and completion latency
// percentiles (as the workers see them), the coordinator's CPU per band
// (/proc/PID/stat), its RSS and open file descriptors, the store's size;
// then checks what must hold whatever the speed: every job succeeded, every
// band accepted exactly once (the store's `bands.completions`), every frame
// identical to the reference. Exit 0 only if all of that holds.
#include <sqlite3.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bench/farm/scale_probe.h"
#include "bench/farm/sim_worker.h"
#include "client/farm_client.h"
#include "common/base/cpu_time.h"
#include "common/base/image.h"
#include "common/farm/types.h"
#include "common/scene/scene_io.h"
#include "worker/band_renderer.h"

using namespace locus::farm_scale;

namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------- the checks

// Bands of the run's jobs accepted other than exactly once, from the store.
long bands_not_accepted_once(const std::string& db_path, long* bands_seen) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    std::fprintf(stderr, "%s: %s\n", db_path.c_str(), sqlite3_errmsg(db));
    sqlite3_close(db);
    return -1;
  }
  long bad = -1;
  sqlite3_stmt* st = nullptr;
  const char* sql = "SELECT count(*), coalesce(sum(completions != 1), 0) FROM bands";
  if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) == SQLITE_OK &&
      sqlite3_step(st) == SQLITE_ROW) {
    *bands_seen = sqlite3_column_int64(st, 0);
    bad = sqlite3_column_int64(st, 1);
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return bad;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-farm-scale: one coordinator, many simulated workers"};
  std::string farm, data, scene_path, reference_out;
  int pid = 0, workers = 100, jobs = 4, frames = 5, width = 256, rows = 4, bands = 16;
  int die = 0, stall = 0, late = 0, timeout_s = 600;
  double delay_ms = 0, delay_sigma = 0;
  double measure_queued = 0;  // --measure-queued: seconds of sampling, then stop
  app.add_option("--farm", farm, "Coordinator address (loopback)")->required();
  app.add_option("--data", data, "The coordinator's --data directory (checked at the end)")
      ->required();
  app.add_option("--coordinator-pid", pid, "The coordinator's process (CPU, memory, files)");
  app.add_option("--scene", scene_path, "Scene file")->required();
  app.add_option("--workers", workers, "Simulated workers")->check(CLI::Range(1, 20000));
  app.add_option("--jobs", jobs, "Jobs")->check(CLI::Range(1, 10000));
  app.add_option("--frames", frames, "Frames per job")->check(CLI::Range(1, 100000));
  app.add_option("--bands", bands, "Bands per frame")->check(CLI::Range(1, 100000));
  app.add_option("--width", width, "Frame width")->check(CLI::Range(1, 8192));
  app.add_option("--rows", rows, "Rows per band")->check(CLI::Range(1, 8192));
  app.add_option("--delay-ms", delay_ms, "Time a worker takes per band (median); 0: none");
  app.add_option("--delay-sigma", delay_sigma, "Log-normal spread of that time; 0: fixed");
  bool no_next = false;
  bool no_png_deflate = false;
  int batch = 1;
  int revive_ms = 0;
  bool outage_ok = false;
  app.add_option("--revive-ms", revive_ms,
                 "A --die worker reconnects as a new worker after this long, and dies again after "
                 "its next lease (0: never)")
      ->check(CLI::Range(0, 3600000) & !CLI::Range(1, 999));
  app.add_flag("--outage-ok", outage_ok,
               "The coordinator restarts during the run: calls failed meanwhile are counted as "
               "outage_errors, not errors");
  app.add_option("--batch", batch,
                 "Bands per call: up to this many leased in one answer (GetTaskRequest.max_bands) "
                 "and returned together in one CompleteBand (CompleteBandRequest.more)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--no-next", no_next,
               "Lease each band with a GetTask (not with the last result's answer)");
  app.add_flag("--no-png-deflate", no_png_deflate,
               "Do not offer png8+deflate: PNG jobs' bands travel as rgb8+zstd, the frames "
               "are encoded by the coordinator");
  app.add_option("--die", die, "Workers that drop their connection after their first lease");
  app.add_option("--stall", stall, "Workers that go silent after their first lease");
  app.add_option("--late", late, "Workers that return each band after its lease lapsed");
  app.add_option("--timeout", timeout_s, "Seconds before the run is called failed");
  app.add_option("--measure-queued", measure_queued,
                 "Big jobs (issue #25): after the submit, time `locus status` and sample the "
                 "coordinator's memory for this many seconds while the bands stay queued, then "
                 "stop without finishing the jobs");
  app.add_option("--reference-out", reference_out, "Write the reference frame here (PNG)");
  CLI11_PARSE(app, argc, argv);
  const int height = rows * bands;

  auto scene = locus::load_scene(scene_path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 2;
  }
  Shared shared;
  shared.address = farm;
  shared.width = width;
  shared.delay_ms = delay_ms;
  shared.delay_sigma = delay_sigma;
  shared.want_next = !no_next;
  shared.png_deflate = !no_png_deflate;
  shared.batch = batch;
  shared.revive_ms = revive_ms;
  shared.outage_ok = outage_ok;
  shared.scene = locus::scene_to_proto(*scene);

  // The reference: the frame through the worker's own renderer, once.
  locus::farm::SubmitRequest request;
  request.scene = shared.scene;
  request.scene_name = fs::path(scene_path).filename().string();
  request.width = width;
  request.height = height;
  request.frame_first = 1;
  request.frame_last = frames;
  request.bands = bands;
  request.output = "frame_####.png";
  {
    locus::farm::BandRenderer renderer(1);
    const std::string hash = locus::farm::content_hash(shared.scene.SerializeAsString());
    if (auto s = renderer.add_scene(hash, shared.scene, request.scene_name); !s.ok()) {
      std::fprintf(stderr, "%s\n", s.message().c_str());
      return 2;
    }
    locus::farm::BandLease whole;
    whole.scene_hash = hash;
    whole.frame = 1;
    whole.y0 = 0;
    whole.y1 = height;
    whole.width = width;
    whole.height = height;
    whole.frame_first = 1;
    whole.frame_last = frames;
    auto out = renderer.render(whole);
    if (!out.ok()) {
      std::fprintf(stderr, "reference: %s\n", out.status().message().c_str());
      return 2;
    }
    shared.frame = std::move(out->rgb);
  }
  locus::Image reference(width, height);
  reference.rgb = shared.frame;
  const std::string reference_path =
      reference_out.empty() ? (fs::path(data) / "reference.png").string() : reference_out;
  if (auto s = locus::write_image(reference_path, reference); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 2;
  }

  // The workers connect and register first; then the jobs arrive.
  Timers timers;
  shared.timers = &timers;
  std::vector<std::unique_ptr<SimWorker>> sims;
  for (int i = 0; i < workers; ++i) {
    Behaviour b = Behaviour::kNormal;
    if (i < die)
      b = Behaviour::kDie;
    else if (i < die + stall)
      b = Behaviour::kStall;
    else if (i < die + stall + late)
      b = Behaviour::kLate;
    sims.push_back(std::make_unique<SimWorker>(shared, i, b));
    if (!sims.back()->start()) return 1;
  }
  for (auto& w : sims) w->poll();
  std::printf("workers_connected %d\n", workers);
  const ProcessSample idle = sample(pid);
  std::printf("coordinator_rss_idle_mib %.1f\ncoordinator_fds_idle %d\n", idle.rss_kib / 1024.0,
              idle.fds);

  // The coordinator's CPU and the heartbeats count from before the first
  // submission: with many jobs, the workers render the first ones while the
  // last are still being submitted.
  const ProcessSample before = sample(pid);
  const double harness_before = locus::process_cpu_seconds();
  std::atomic<bool> done{false};
  long peak_rss = 0;
  int peak_fds = 0;
  std::function<void()> beat = [&] {
    if (done) return;
    for (auto& w : sims) w->heartbeat();
    const ProcessSample p = sample(pid);
    peak_rss = std::max(peak_rss, p.rss_kib);
    peak_fds = std::max(peak_fds, p.fds);
    timers.at(Clock::now() + Ms(1000), beat);
  };
  if (measure_queued == 0) timers.at(Clock::now() + Ms(1000), beat);

  locus::client::FarmClient client(farm);
  std::vector<std::string> job_ids;
  const auto submit_start = Clock::now();
  for (int j = 0; j < jobs; ++j) {
    auto info = client.submit(request);
    if (!info.ok()) {
      std::fprintf(stderr, "submit: %s\n", info.status().message().c_str());
      return 1;
    }
    job_ids.push_back(info->job_id);
  }
  std::printf("submit_seconds %.3f\n", seconds_since(submit_start));
  if (measure_queued > 0) {
    // Big jobs: the status of one job and the list, timed; then the memory
    // while every worker holds a lease and the rest of the bands wait.
    const auto status_start = Clock::now();
    auto one = client.job(job_ids.front());
    std::printf("status_seconds %.3f\n", seconds_since(status_start));
    const auto list_start = Clock::now();
    auto all = client.jobs();
    std::printf("list_seconds %.3f\n", seconds_since(list_start));
    if (!one.ok() || !all.ok()) return 1;
    long peak = 0;
    const auto sampling = Clock::now();
    while (seconds_since(sampling) < measure_queued) {
      for (auto& w : sims) w->heartbeat();
      peak = std::max(peak, sample(pid).rss_kib);
      std::this_thread::sleep_for(Ms(250));
    }
    auto later = client.job(job_ids.front());
    if (!later.ok()) return 1;
    std::printf("bands_total %lld\nbands_done %lld\nbands_running %d\n",
                static_cast<long long>(later->spec.bands_total()),
                static_cast<long long>(later->bands_done), static_cast<int>(later->bands_running));
    std::printf("coordinator_rss_queued_mib %.1f\n", peak / 1024.0);
    std::fflush(stdout);
    std::_Exit(0);  // the simulated workers are not wound down
  }
  const auto start = Clock::now();

  bool all_done = false;
  std::vector<locus::farm::JobInfo> ended;
  // A client's view of the busy farm: each `locus status` of the polling
  // below, timed (a new call on the client's connection).
  std::vector<double> status_ms;
  while (seconds_since(start) < timeout_s) {
    ended.clear();
    bool unfinished = false;
    for (const std::string& id : job_ids) {
      const auto asked = Clock::now();
      auto info = client.job(id);
      status_ms.push_back(seconds_since(asked) * 1000);
      if (!info.ok()) {
        std::fprintf(stderr, "job %s: %s\n", id.c_str(), info.status().message().c_str());
        unfinished = true;
        break;
      }
      if (!locus::farm::is_terminal(info->state)) {
        unfinished = true;
        break;
      }
      ended.push_back(*info);
    }
    if (!unfinished) {
      all_done = true;
      break;
    }
    std::this_thread::sleep_for(Ms(100));
  }
  const ProcessSample after = sample(pid);
  const double harness_cpu = locus::process_cpu_seconds() - harness_before;
  done = true;
  shared.stopping = true;
  for (auto& w : sims) w->stop();
  for (int i = 0; i < 100; ++i) {
    size_t n = 0;
    for (auto& w : sims) n += w->in_flight();
    if (n == 0) break;
    std::this_thread::sleep_for(Ms(50));
  }

  const int64_t total_bands = static_cast<int64_t>(jobs) * frames * bands;
  double window = 0;
  int64_t accepted = 0, refused = 0, errors = 0, fetches = 0, heartbeats = 0, registrations = 0;
  int64_t get_tasks = 0, with_answer = 0, outage_errors = 0, revived = 0, complete_calls = 0;
  std::vector<double> dispatch, completion;
  {
    std::lock_guard lk(shared.mu);
    window = std::chrono::duration<double>(shared.last_accept - shared.first_accept).count();
    accepted = shared.accepted;
    refused = shared.refused;
    errors = shared.errors;
    fetches = shared.scene_fetches;
    heartbeats = shared.heartbeats;
    registrations = shared.registrations;
    get_tasks = shared.get_tasks;
    outage_errors = shared.outage_errors;
    revived = shared.revived;
    with_answer = shared.with_answer;
    complete_calls = shared.complete_calls;
    dispatch = shared.dispatch_ms;
    completion = shared.completion_ms;
  }
  const double cpu = after.cpu_seconds - before.cpu_seconds;
  std::printf("bands %lld\naccepted %lld\nrefused %lld\nrpc_errors %lld\nscene_fetches %lld\n",
              static_cast<long long>(total_bands), static_cast<long long>(accepted),
              static_cast<long long>(refused), static_cast<long long>(errors),
              static_cast<long long>(fetches));
  std::printf("heartbeats %lld\nregistered_again %lld\n", static_cast<long long>(heartbeats),
              static_cast<long long>(registrations));
  // Calls per band: GetTask is saved for each band leased with an answer.
  std::printf("get_tasks %lld\nbands_with_answer %lld\ncomplete_calls %lld\n",
              static_cast<long long>(get_tasks), static_cast<long long>(with_answer),
              static_cast<long long>(complete_calls));
  std::printf("outage_errors %lld\nworkers_revived %lld\n", static_cast<long long>(outage_errors),
              static_cast<long long>(revived));
  std::printf("seconds %.3f\nbands_per_second %.0f\n", window,
              window > 0 ? static_cast<double>(accepted) / window : 0.0);
  std::printf("dispatch_ms_p50 %.3f\ndispatch_ms_p99 %.3f\ndispatch_ms_max %.3f\n",
              percentile(dispatch, 0.5), percentile(dispatch, 0.99), percentile(dispatch, 1.0));
  std::printf("completion_ms_p50 %.3f\ncompletion_ms_p99 %.3f\ncompletion_ms_max %.3f\n",
              percentile(completion, 0.5), percentile(completion, 0.99),
              percentile(completion, 1.0));
  std::printf("status_ms_p50 %.3f\nstatus_ms_max %.3f\n", percentile(status_ms, 0.5),
              percentile(status_ms, 1.0));
  if (pid > 0) {
    std::printf("coordinator_cpu_seconds %.3f\ncoordinator_cpu_us_per_band %.1f\n", cpu,
                accepted > 0 ? cpu * 1e6 / static_cast<double>(accepted) : 0.0);
    std::printf("coordinator_rss_peak_mib %.1f\ncoordinator_fds_peak %d\n", peak_rss / 1024.0,
                peak_fds);
  }
  // The simulated workers share the machine with the coordinator: what they
  // took of it bounds what the coordinator could have had.
  std::printf("harness_cpu_seconds %.3f\n", harness_cpu);
  std::printf("store_bytes %ju\n", tree_bytes(data));

  // What must hold, whatever the speed.
  int failures = 0;
  if (errors > 0) {
    std::printf("FAIL: %lld calls failed (other than a dropped worker's)\n",
                static_cast<long long>(errors));
    ++failures;
  }
  if (late > 0 && refused == 0) {
    std::printf("FAIL: --late workers, but no result was refused (a run shorter than a lease?)\n");
    ++failures;
  }
  if (!all_done) {
    std::printf("FAIL: jobs not finished after %d s\n", timeout_s);
    ++failures;
  }
  for (const auto& j : ended) {
    if (j.state != locus::farm::JobState::kSucceeded) {
      std::printf("FAIL: job %s %s: %s\n", j.job_id.c_str(), locus::farm::job_state_name(j.state),
                  j.error.c_str());
      ++failures;
    }
  }
  long bands_seen = 0;
  const long twice = bands_not_accepted_once((fs::path(data) / "locus.db").string(), &bands_seen);
  std::printf("store_bands %ld\nstore_bands_not_accepted_once %ld\n", bands_seen, twice);
  if (twice != 0 || bands_seen != total_bands) {
    std::printf("FAIL: the store has %ld bands (want %lld), %ld not accepted exactly once\n",
                bands_seen, static_cast<long long>(total_bands), twice);
    ++failures;
  }
  if (all_done) {
    int compared = 0;
    for (const std::string& id : job_ids) {
      for (int f = 1; f <= frames; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%04d.png", f);
        const std::string path = (fs::path(data) / "jobs" / id / name).string();
        auto got = locus::read_image(path);
        auto want = locus::read_image(reference_path);
        if (!got.ok() || !want.ok() || got->rgb != want->rgb) {
          std::printf("FAIL: %s differs from the reference (or is missing)\n", path.c_str());
          ++failures;
        } else {
          ++compared;
        }
      }
    }
    std::printf("frames_identical %d\n", compared);
  }
  std::printf("%s\n", failures == 0 ? "ok" : "FAILED");
  return failures == 0 ? 0 : 1;
}
