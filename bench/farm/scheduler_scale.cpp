// locus-scheduler-scale: the Scheduler's cost per band against the farm's
// size, without a network (issue #25 item 3; bench/results/farm-scale-slope.md).
// On a fake clock, best of 3:
//   cycle: a worker's heartbeat, its band's completion and its next lease,
//     and the dispatch thread's has_queued_bands(), every worker holding a
//     lease: at 10 and 1,000 workers, and with 0 and 10,000 finished jobs
//     kept (100 workers);
//   idle poll: a GetTask of a worker when every band is leased (speculation
//     is looked for, and none is due), at 10 and 1,000 live leases.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "server/scheduler.h"

namespace {

using locus::farm::BandLease;
using locus::farm::BandOutput;
using locus::farm::JobSpec;
using locus::farm::Millis;
using locus::farm::Scheduler;
using locus::farm::SchedulerOptions;
using locus::farm::TimePoint;
using Clock = std::chrono::steady_clock;

TimePoint fake_now{};

JobSpec job_spec(int frames, int bands) {
  JobSpec s;
  s.scene_hash = "hash";
  s.scene_name = "bench";
  s.width = 4;
  s.height = bands;
  s.frame_first = 1;
  s.frame_last = frames;
  s.bands = bands;
  s.output = "f_####.png";
  return s;
}

BandOutput pixels(const std::string& worker, const BandLease& lease) {
  BandOutput o;
  o.worker_id = worker;
  o.lease_id = lease.lease_id;
  o.rgb.assign(static_cast<size_t>(lease.width) * (lease.y1 - lease.y0) * 3, 0.5f);
  return o;
}

Scheduler make_scheduler() {
  SchedulerOptions o;
  o.lease = Millis(100000000);  // nothing lapses while the clock runs
  o.worker_timeout = Millis(100000000);
  return Scheduler(o, [] { return fake_now; });
}

std::string worker_name(int i) { return std::string("w").append(std::to_string(i)); }

double us_since(Clock::time_point start, int n) {
  return std::chrono::duration<double, std::micro>(Clock::now() - start).count() / n;
}

double cycle_us(int workers, int finished_jobs) {
  Scheduler s = make_scheduler();
  for (int j = 0; j < finished_jobs; ++j) s.cancel(s.add_job(job_spec(1, 1)));
  s.add_job(job_spec(100000, 100));
  std::vector<std::string> ids;
  std::vector<BandLease> held;
  for (int i = 0; i < workers; ++i) {
    ids.push_back(s.add_worker(worker_name(i), 1));
    held.push_back(**s.next_band(ids.back()));
  }
  s.take_events();
  constexpr int kBands = 200000;
  const auto start = Clock::now();
  for (int k = 0; k < kBands; ++k) {
    const int i = k % workers;
    fake_now += Millis(1);
    (void)s.heartbeat(ids[i], {held[i].lease_id});
    (void)s.complete_band(pixels(ids[i], held[i]));
    held[i] = **s.next_band(ids[i]);
    (void)s.has_queued_bands();
    if (k % 64 == 0) s.take_events();  // the coordinator's persist()
  }
  return us_since(start, kBands);
}

double idle_poll_us(int leases) {
  Scheduler s = make_scheduler();
  s.add_job(job_spec(1, leases + 3));
  const std::string idle = s.add_worker("idle", 1);
  for (int i = 0; i < 3; ++i) {  // three peers: speculation has a threshold
    const BandLease l = **s.next_band(idle);
    fake_now += Millis(10);
    (void)s.complete_band(pixels(idle, l));
  }
  for (int i = 0; i < leases; ++i) (void)s.next_band(s.add_worker(worker_name(i), 1));
  s.take_events();
  fake_now += Millis(20);  // every lease younger than the threshold
  constexpr int kPolls = 20000;
  const auto start = Clock::now();
  for (int k = 0; k < kPolls; ++k) (void)s.next_band(idle);
  return us_since(start, kPolls);
}

template <typename F>
double best_of_3(F f) {
  double best = f();
  for (int i = 0; i < 2; ++i) best = std::min(best, f());
  return best;
}

}  // namespace

int main() {
  spdlog::set_level(spdlog::level::off);
  std::printf("cycle_us_10_workers %.3f\n", best_of_3([] { return cycle_us(10, 0); }));
  std::printf("cycle_us_1000_workers %.3f\n", best_of_3([] { return cycle_us(1000, 0); }));
  std::printf("cycle_us_0_finished_jobs %.3f\n", best_of_3([] { return cycle_us(100, 0); }));
  std::printf("cycle_us_10000_finished_jobs %.3f\n",
              best_of_3([] { return cycle_us(100, 10000); }));
  std::printf("idle_poll_us_10_leases %.3f\n", best_of_3([] { return idle_poll_us(10); }));
  std::printf("idle_poll_us_1000_leases %.3f\n", best_of_3([] { return idle_poll_us(1000); }));
}
