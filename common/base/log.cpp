#include "common/base/log.h"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <utility>

namespace locus {
namespace {

// The band this thread works on.
using BandIds = BandLogIds;
thread_local BandIds current_band;

// %* in the text pattern: "[job j0001 frame 3 band 7] ", or nothing.
class BandFlag final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg&, const std::tm&,
              spdlog::memory_buf_t& dest) override {
    const BandIds& ids = current_band;
    if (ids.job.empty()) return;
    std::string s = "[job " + ids.job;
    if (ids.frame >= 0) s += " frame " + std::to_string(ids.frame);
    if (ids.band >= 0) s += " band " + std::to_string(ids.band);
    s += "] ";
    dest.append(s.data(), s.data() + s.size());
  }
  std::unique_ptr<custom_flag_formatter> clone() const override {
    return std::make_unique<BandFlag>();
  }
};

// One JSON object per line: time (UTC, ms), level, logger, msg, and the
// band's ids when the thread has them.
class JsonFormatter final : public spdlog::formatter {
 public:
  void format(const spdlog::details::log_msg& msg, spdlog::memory_buf_t& dest) override {
    const auto since_epoch = msg.time.time_since_epoch();
    const auto secs = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(since_epoch - secs);
    const std::time_t t = secs.count();
    std::tm tm{};
    gmtime_r(&t, &tm);
    std::array<char, 40> time{};
    const size_t n = std::strftime(time.data(), time.size(), "%Y-%m-%dT%H:%M:%S", &tm);
    std::snprintf(time.data() + n, time.size() - n, ".%03dZ", static_cast<int>(ms.count()));

    const auto level = spdlog::level::to_string_view(msg.level);
    std::string s = "{\"time\":\"" + std::string(time.data()) + "\",\"level\":\"" +
                    std::string(level.data(), level.size()) + "\",\"logger\":\"" +
                    json_escape(std::string_view(msg.logger_name.data(), msg.logger_name.size())) +
                    "\",\"msg\":\"" +
                    json_escape(std::string_view(msg.payload.data(), msg.payload.size())) + "\"";
    const BandIds& ids = current_band;
    if (!ids.job.empty()) s += ",\"job\":\"" + json_escape(ids.job) + "\"";
    if (ids.frame >= 0) s += ",\"frame\":" + std::to_string(ids.frame);
    if (ids.band >= 0) s += ",\"band\":" + std::to_string(ids.band);
    s += "}\n";
    dest.append(s.data(), s.data() + s.size());
  }
  std::unique_ptr<spdlog::formatter> clone() const override {
    return std::make_unique<JsonFormatter>();
  }
};

// Length of the valid UTF-8 sequence at s[i], or 0 (RFC 3629: no overlong
// forms, no surrogates, nothing past U+10FFFF).
size_t utf8_length(std::string_view s, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // the range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;
    if (c == 0xED) hi = 0x9F;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;
    if (c == 0xF4) hi = 0x8F;
  } else {
    return 0;
  }
  if (i + n > s.size() || byte(i + 1) < lo || byte(i + 1) > hi) return 0;
  for (size_t k = 2; k < n; ++k) {
    if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return 0;
  }
  return n;
}

}  // namespace

Result<LogFormat> parse_log_format(std::string_view name) {
  if (const auto format = label_value(kLogFormatLabels, name)) return *format;
  return InvalidArgument("--log-format '" + std::string(name) + "': expected " +
                         label_choices(kLogFormatLabels));
}

std::unique_ptr<spdlog::formatter> make_log_formatter(LogFormat format) {
  if (format == LogFormat::kJson) return std::make_unique<JsonFormatter>();
  auto f = std::make_unique<spdlog::pattern_formatter>();
  f->add_flag<BandFlag>('*').set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%n] [%^%l%$] %*%v");
  return f;
}

namespace {

// The active captures; the sink offers each line to all of them (the
// worker has one at a time; the tests run several workers in a process).
std::mutex captures_mu;
std::vector<BandLogCapture*> captures;

class CaptureSink final : public spdlog::sinks::base_sink<std::mutex> {
 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    if (msg.level < spdlog::level::info) return;
    const BandIds& ids = current_band;
    if (ids.job.empty()) return;
    std::lock_guard lk(captures_mu);
    if (captures.empty()) return;
    const std::time_t t = std::chrono::system_clock::to_time_t(msg.time);
    std::tm tm{};
    localtime_r(&t, &tm);
    char stamp[32];
    const auto ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(msg.time.time_since_epoch()).count() %
        1000;
    std::snprintf(stamp, sizeof stamp, "%02d:%02d:%02d.%03d ", tm.tm_hour, tm.tm_min, tm.tm_sec,
                  static_cast<int>(ms));
    const auto level = spdlog::level::to_string_view(msg.level);
    std::string line = stamp + std::string(level.data(), level.size()) + " " +
                       std::string(msg.payload.data(), msg.payload.size());
    for (BandLogCapture* c : captures) c->offer(ids, line);
  }
  void flush_() override {}
};

std::shared_ptr<CaptureSink>& capture_sink() {
  static auto sink = std::make_shared<CaptureSink>();
  return sink;
}

void add_capture_sink(spdlog::logger& logger) {
  auto& sinks = logger.sinks();
  if (std::find(sinks.begin(), sinks.end(), capture_sink()) == sinks.end())
    sinks.push_back(capture_sink());
}

}  // namespace

void install_band_log_capture() { add_capture_sink(*spdlog::default_logger()); }

BandLogIds current_band_log_ids() { return current_band; }

BandLogCapture::BandLogCapture(std::string job, int frame, int band)
    : ids_{std::move(job), frame, band} {
  std::lock_guard lk(captures_mu);
  captures.push_back(this);
}

BandLogCapture::~BandLogCapture() {
  std::lock_guard lk(captures_mu);
  captures.erase(std::remove(captures.begin(), captures.end(), this), captures.end());
}

void BandLogCapture::offer(const BandLogIds& ids, const std::string& line) {
  // captures_mu held.
  if (ids.job != ids_.job || ids.frame != ids_.frame || ids.band != ids_.band) return;
  if (lines_.size() >= kMaxBandLogLines) {
    ++dropped_;
    return;
  }
  lines_.push_back(line.substr(0, kMaxBandLogLineBytes));
}

std::vector<std::string> BandLogCapture::take() {
  std::lock_guard lk(captures_mu);
  std::vector<std::string> out = std::exchange(lines_, {});
  if (dropped_ > 0) out.push_back("... " + std::to_string(dropped_) + " more lines not kept");
  dropped_ = 0;
  return out;
}

Status setup_logging(LogFormat format, std::string_view level) {
  const auto known = label_value(kLogLevelLabels, level);
  if (!known) {
    return InvalidArgument("--log-level '" + std::string(level) + "': expected " +
                           label_choices(kLogLevelLabels));
  }
  // JSON lines are for machines: no colour codes in them.
  std::shared_ptr<spdlog::sinks::sink> sink;
  if (format == LogFormat::kJson) {
    sink = std::make_shared<spdlog::sinks::stderr_sink_mt>();
  } else {
    sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  }
  auto logger = std::make_shared<spdlog::logger>("locus", std::move(sink));
  logger->set_formatter(make_log_formatter(format));
  logger->set_level(*known);
  add_capture_sink(*logger);
  spdlog::set_default_logger(std::move(logger));
  return Status::Ok();
}

BandLogScope::BandLogScope(std::string job, int frame, int band)
    : job_(std::exchange(current_band.job, std::move(job))),
      frame_(std::exchange(current_band.frame, frame)),
      band_(std::exchange(current_band.band, band)) {}

BandLogScope::~BandLogScope() {
  current_band.job = std::move(job_);
  current_band.frame = frame_;
  current_band.band = band_;
}

std::string json_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size() + 8);
  for (size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x80) {
      const size_t n = utf8_length(text, i);
      if (n == 0) {
        out += "\xEF\xBF\xBD";  // U+FFFD for a byte that starts no valid sequence
        ++i;
      } else {
        out.append(text.substr(i, n));
        i += n;
      }
      continue;
    }
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (c < 0x20 || c == 0x7f) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
    ++i;
  }
  return out;
}

}  // namespace locus
