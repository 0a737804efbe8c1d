// Job progress for people and for logs: on a terminal, one bar redrawn in
// place (bands and frames done, throughput, ETA); otherwise one plain line
// per update.
#pragma once

#include <cstdio>
#include <string>

#include "common/farm/types.h"

namespace locus::client {

class Progress {
 public:
  Progress(std::FILE* out, bool tty) : out_(out), tty_(tty) {}
  void update(const farm::JobInfo& job);
  // Ends the bar's line.
  void finish();

 private:
  std::FILE* out_;
  bool tty_;
  bool drawn_ = false;
  std::string last_;
};

// "1.5 s", "2 min 05 s", "1 h 02 min".
std::string format_duration(double seconds);

}  // namespace locus::client
