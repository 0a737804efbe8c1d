#include "client/progress.h"

#include <algorithm>
#include <cmath>

namespace locus::client {

std::string format_duration(double s) {
  char buf[64];
  if (!std::isfinite(s) || s < 0) return "?";
  if (s < 60) {
    std::snprintf(buf, sizeof buf, "%.1f s", s);
  } else if (s < 3600) {
    std::snprintf(buf, sizeof buf, "%d min %02d s", static_cast<int>(s) / 60,
                  static_cast<int>(s) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%d h %02d min", static_cast<int>(s) / 3600,
                  static_cast<int>(s) / 60 % 60);
  }
  return buf;
}

void Progress::update(const farm::JobInfo& j) {
  const int64_t total = j.spec.bands_total();
  const double rate = j.seconds_elapsed > 0 ? j.bands_done / j.seconds_elapsed : 0.0;
  const std::string eta = farm::is_terminal(j.state) ? "0 s"
                          : rate > 0 ? format_duration((total - j.bands_done) / rate)
                                     : "?";
  char counts[256];
  std::snprintf(counts, sizeof counts, "%lld/%lld bands  %d/%d frames  %.1f bands/s  ETA %s",
                static_cast<long long>(j.bands_done), static_cast<long long>(total), j.frames_done,
                j.spec.frames(), rate, eta.c_str());
  const std::string line = j.job_id + " " + farm::job_state_name(j.state) + "  " + counts;
  if (line == last_) return;
  last_ = line;
  if (!tty_) {
    std::fprintf(out_, "%s\n", line.c_str());
    std::fflush(out_);
    return;
  }
  constexpr int kWidth = 30;
  const double done = total > 0 ? static_cast<double>(j.bands_done) / total : 0.0;
  const int filled = std::clamp(static_cast<int>(done * kWidth), 0, kWidth);
  std::fprintf(out_, "\r\033[K%s [%s%s] %3d%%  %s", j.job_id.c_str(),
               std::string(filled, '#').c_str(), std::string(kWidth - filled, '.').c_str(),
               static_cast<int>(done * 100), counts);
  std::fflush(out_);
  drawn_ = true;
}

void Progress::finish() {
  if (tty_ && drawn_) std::fprintf(out_, "\n");
  drawn_ = false;
}

}  // namespace locus::client
