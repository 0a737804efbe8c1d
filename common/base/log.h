// The processes' logs: spdlog on stderr, as text lines or one JSON object
// per line (`--log-format json`, for log collectors in containers). A line
// written while a thread works on a band carries the band's ids: the job,
// the frame and the band (BandLogScope), as fields in JSON and as a
// "[job j0001 frame 3 band 7]" prefix in text.
#pragma once

#include <spdlog/common.h>
#include <spdlog/formatter.h>

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/labels.h"
#include "common/base/status.h"

namespace locus {

enum class LogFormat { kText, kJson };
// The names of --log-format and --log-level, for parsing, messages and
// --help of every process.
inline constexpr Labels<LogFormat, 2> kLogFormatLabels = {
    {{LogFormat::kText, "text"}, {LogFormat::kJson, "json"}}};
inline constexpr Labels<spdlog::level::level_enum, 7> kLogLevelLabels = {
    {{spdlog::level::trace, "trace"},
     {spdlog::level::debug, "debug"},
     {spdlog::level::info, "info"},
     {spdlog::level::warn, "warn"},
     {spdlog::level::err, "error"},
     {spdlog::level::critical, "critical"},
     {spdlog::level::off, "off"}}};
// "text" or "json"; otherwise InvalidArgument naming the flag.
Result<LogFormat> parse_log_format(std::string_view name);

// The default logger "locus" on stderr in `format`, at `level` ("info",
// "debug", "warn", ...; InvalidArgument otherwise). stdout stays for what
// scripts read.
Status setup_logging(LogFormat format, std::string_view level = "info");

// The formatter setup_logging() installs, for tests.
std::unique_ptr<spdlog::formatter> make_log_formatter(LogFormat format);

// The ids of a band a line is logged for; job empty: none.
struct BandLogIds {
  std::string job;
  int frame = -1;
  int band = -1;
};
// The calling thread's, for a thread it starts to work on the same band
// (render_band's pool): BandLogScope(ids) there.
BandLogIds current_band_log_ids();

// The ids of the band this thread works on, while in scope (nested scopes
// restore the outer ids). frame or band -1: not known (a job-wide line).
class BandLogScope {
 public:
  explicit BandLogScope(std::string job, int frame = -1, int band = -1);
  // The ids of another thread (current_band_log_ids()).
  explicit BandLogScope(const BandLogIds& ids) : BandLogScope(ids.job, ids.frame, ids.band) {}
  ~BandLogScope();
  BandLogScope(const BandLogScope&) = delete;
  BandLogScope& operator=(const BandLogScope&) = delete;

 private:
  std::string job_;
  int frame_, band_;
};

// While alive, collects the lines logged (at info and above, by any thread
// of the process) under BandLogScope ids equal to its own: the band's log,
// which the worker sends with the band's result (`locus logs`). At most
// kMaxBandLogLines lines of kMaxBandLogLineBytes; past that they are
// counted. Needs the capture sink on the default logger: setup_logging()
// installs it, install_band_log_capture() does for any other logger (call
// both before other threads log).
inline constexpr size_t kMaxBandLogLines = 200;
inline constexpr size_t kMaxBandLogLineBytes = 1000;
void install_band_log_capture();
class BandLogCapture {
 public:
  BandLogCapture(std::string job, int frame, int band);
  ~BandLogCapture();
  BandLogCapture(const BandLogCapture&) = delete;
  BandLogCapture& operator=(const BandLogCapture&) = delete;
  // The lines so far ("12:03:04.512 warning text"), and a last one saying
  // how many were left out; the capture starts afresh.
  std::vector<std::string> take();
  // The capture sink's: a line logged under `ids`.
  void offer(const BandLogIds& ids, const std::string& line);

 private:
  BandLogIds ids_;
  std::vector<std::string> lines_;
  size_t dropped_ = 0;
};

// `text` as the body of a JSON string: quotes, backslashes and control
// characters escaped, invalid UTF-8 replaced by U+FFFD.
std::string json_escape(std::string_view text);

}  // namespace locus
