// Running a helper program to its end (ffmpeg for movies, the
// coordinator's --notify-cmd): no shell unless asked for, stdin from
// /dev/null, its output to a file, a time limit and a way to stop it.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "common/base/status.h"
#include "common/farm/types.h"

namespace locus::farm {

struct ProcessRun {
  std::vector<std::string> argv;  // argv[0] is looked up on the PATH
  // Added to (or replacing in) this process's environment.
  std::vector<std::pair<std::string, std::string>> env;
  std::string output_path;  // stdout and stderr; empty: /dev/null
  Millis timeout{60000};
  std::function<bool()> cancelled;  // polled every 50 ms; true: killed
};

struct ProcessResult {
  int exit_code = -1;  // -1: killed by a signal
  int signal = 0;
  std::string last_line;  // of its output, shortened (empty without output_path)
};

// NotFound when argv[0] cannot be run; Cancelled or DeadlineExceeded when
// it was killed (SIGKILL) for `cancelled` or the time limit. Otherwise the
// way it ended, whatever its exit code.
Result<ProcessResult> run_process(const ProcessRun& run);

}  // namespace locus::farm
