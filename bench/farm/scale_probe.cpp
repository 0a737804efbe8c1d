#include "bench/farm/scale_probe.h"

#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>
#include <utility>

namespace locus::farm_scale {

namespace fs = std::filesystem;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// ---------------------------------------------------------------- the process

ProcessSample sample(int pid) {
  ProcessSample s;
  if (pid <= 0) return s;
  const std::string dir = "/proc/" + std::to_string(pid);
  {
    std::ifstream f(dir + "/stat");
    std::string line;
    std::getline(f, line);
    // Fields after the command's closing parenthesis; utime and stime are
    // the 14th and 15th of the line, the 12th and 13th after it.
    const size_t close = line.rfind(')');
    if (close != std::string::npos) {
      std::istringstream rest(line.substr(close + 2));
      std::string field;
      long utime = 0, stime = 0;
      for (int i = 1; i <= 13 && rest >> field; ++i) {
        if (i == 12) utime = std::stol(field);
        if (i == 13) stime = std::stol(field);
      }
      s.cpu_seconds =
          static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
    }
  }
  std::ifstream f(dir + "/status");
  std::string key;
  while (f >> key) {
    if (key == "VmRSS:") f >> s.rss_kib;
    if (key == "VmHWM:") f >> s.hwm_kib;
  }
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir + "/fd", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    ++s.fds;
  }
  return s;
}

uintmax_t tree_bytes(const std::string& dir) {
  uintmax_t n = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file(ec)) n += it->file_size(ec);
  }
  return n;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// ---------------------------------------------------------------- timers

Timers::Timers() : thread_([this] { run(); }) {}

Timers::~Timers() {
  {
    std::lock_guard lk(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void Timers::at(Clock::time_point when, std::function<void()> fn) {
  {
    std::lock_guard lk(mu_);
    queue_.push({when, seq_++, std::move(fn)});
  }
  cv_.notify_all();
}

void Timers::run() {
  std::unique_lock lk(mu_);
  while (!stop_) {
    if (queue_.empty()) {
      cv_.wait(lk);
      continue;
    }
    if (queue_.top().when > Clock::now()) {
      cv_.wait_until(lk, queue_.top().when);
      continue;
    }
    std::function<void()> fn = queue_.top().fn;
    queue_.pop();
    lk.unlock();
    fn();
    lk.lock();
  }
}

}  // namespace locus::farm_scale
