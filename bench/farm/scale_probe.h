// What locus-farm-scale (bench/farm/scale.cpp) measures with: the
// coordinator's process as /proc shows it (CPU, memory, open files), the
// store's bytes on disk, percentiles of latencies (this process's own CPU:
// common/base/cpu_time.h);
// and `Timers`, the one thread that runs the simulated workers' delays,
// retries and heartbeats at their time.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <queue>
#include <string>
#include <thread>
#include <vector>

namespace locus::farm_scale {

using Clock = std::chrono::steady_clock;

// Seconds from t to now.
double seconds_since(Clock::time_point t);

// ---------------------------------------------------------------- the process

struct ProcessSample {
  double cpu_seconds = 0;  // user + system
  long rss_kib = 0;
  long hwm_kib = 0;
  int fds = 0;
};

// Process pid's CPU, memory and open files from /proc (all zero for pid <= 0).
ProcessSample sample(int pid);

// The bytes of the regular files below dir.
uintmax_t tree_bytes(const std::string& dir);

// The q-quantile of v (q in [0, 1]; 1: the largest); 0 for no values.
double percentile(std::vector<double> v, double q);

// ---------------------------------------------------------------- timers

// One thread running functions at their time (delays, retries, heartbeats).
class Timers {
 public:
  Timers();
  ~Timers();
  void at(Clock::time_point when, std::function<void()> fn);

 private:
  struct Entry {
    Clock::time_point when;
    uint64_t seq;
    std::function<void()> fn;
    bool operator>(const Entry& o) const { return when != o.when ? when > o.when : seq > o.seq; }
  };
  void run();
  std::mutex mu_;
  std::condition_variable cv_;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue_;
  uint64_t seq_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace locus::farm_scale
