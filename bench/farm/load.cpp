// locus-farm-load: the farm under many clients (bench/farm/load.sh runs it).
// N client threads, each with its own connection, submit J jobs between
// them (each a frame of B bands of one pixel row), then follow every job to
// its end. Meanwhile the coordinator's resident memory is sampled from
// /proc. Prints "key value" lines; exit 0 only if every job succeeded.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "client/farm_client.h"
#include "common/scene/scene_io.h"

namespace {

using Clock = std::chrono::steady_clock;

// VmRSS and VmHWM of a process, in KiB (0 when unreadable).
std::pair<long, long> rss_kib(int pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  long rss = 0, hwm = 0;
  while (f >> key) {
    if (key == "VmRSS:") f >> rss;
    if (key == "VmHWM:") f >> hwm;
  }
  return {rss, hwm};
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-farm-load: many clients submitting small jobs to one farm"};
  std::string farm, scene_path;
  int clients = 50, jobs = 200, bands = 50, width = 64, pid = 0;
  app.add_option("--farm", farm, "Coordinator address")->required();
  app.add_option("--scene", scene_path, "Scene file")->required();
  app.add_option("--clients", clients, "Concurrent clients")->check(CLI::Range(1, 1000));
  app.add_option("--jobs", jobs, "Jobs in all")->check(CLI::Range(1, 100000));
  app.add_option("--bands", bands, "Bands per job (one frame of this many rows)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--width", width, "Frame width")->check(CLI::Range(1, 4096));
  app.add_option("--coordinator-pid", pid, "Process whose memory is sampled");
  CLI11_PARSE(app, argc, argv);

  auto scene = locus::load_scene(scene_path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 1;
  }
  locus::farm::SubmitRequest base;
  base.scene = locus::scene_to_proto(*scene);
  base.scene_name = scene_path;
  base.width = width;
  base.height = bands;
  base.bands = bands;
  base.output = "load.png";

  std::atomic<bool> done{false};
  std::atomic<int> finished{0};
  long rss_first = pid ? rss_kib(pid).first : 0, rss_max = rss_first;
  std::vector<std::pair<int, long>> rss_by_progress;  // (jobs finished, KiB)
  std::thread sampler([&] {
    int next_mark = 0;
    while (!done) {
      if (pid) {
        const long rss = rss_kib(pid).first;
        rss_max = std::max(rss_max, rss);
        if (finished >= next_mark) {
          rss_by_progress.push_back({finished.load(), rss});
          next_mark += std::max(1, jobs / 4);
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });

  std::mutex mu;
  std::vector<double> submit_ms, job_s;
  int ok = 0, bad = 0;
  const auto start = Clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c) {
    threads.emplace_back([&, c] {
      locus::client::FarmClient client(farm);
      std::vector<std::pair<std::string, Clock::time_point>> mine;
      for (int j = c; j < jobs; j += clients) {
        locus::farm::SubmitRequest r = base;
        r.orbit_degrees = 0;
        const auto t0 = Clock::now();
        auto submitted = client.submit(r);
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        std::lock_guard lk(mu);
        submit_ms.push_back(ms);
        if (submitted.ok()) {
          mine.push_back({submitted->job_id, t0});
        } else {
          ++bad;
          std::fprintf(stderr, "submit: %s\n", submitted.status().message().c_str());
        }
      }
      for (const auto& [id, t0] : mine) {
        auto end = client.watch(id, [](const locus::farm::JobInfo&) {});
        const double s = std::chrono::duration<double>(Clock::now() - t0).count();
        std::lock_guard lk(mu);
        ++finished;
        job_s.push_back(s);
        if (end.ok() && end->state == locus::farm::JobState::kSucceeded &&
            end->bands_done == bands) {
          ++ok;
        } else {
          ++bad;
          std::fprintf(
              stderr, "job %s: %s\n", id.c_str(),
              end.ok() ? (std::string(locus::farm::job_state_name(end->state)) + " " + end->error)
                             .c_str()
                       : end.status().message().c_str());
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  done = true;
  sampler.join();
  const auto [rss_end, hwm] = pid ? rss_kib(pid) : std::pair<long, long>{0, 0};

  std::printf("clients %d\njobs %d\njobs_succeeded %d\njobs_failed %d\nbands_total %lld\n", clients,
              jobs, ok, bad, static_cast<long long>(jobs) * bands);
  std::printf("seconds %.2f\nbands_per_second %.0f\n", seconds, jobs * bands / seconds);
  std::printf("submit_p50_ms %.2f\nsubmit_p99_ms %.2f\n", percentile(submit_ms, 0.5),
              percentile(submit_ms, 0.99));
  std::printf("job_p50_s %.2f\njob_p99_s %.2f\n", percentile(job_s, 0.5), percentile(job_s, 0.99));
  if (pid) {
    std::printf("rss_start_kib %ld\nrss_max_kib %ld\nrss_end_kib %ld\nrss_hwm_kib %ld\n", rss_first,
                rss_max, rss_end, hwm);
    for (const auto& [n, kib] : rss_by_progress) std::printf("rss_at_jobs_done %d %ld\n", n, kib);
  }
  return bad == 0 ? 0 : 1;
}
