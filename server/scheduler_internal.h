// Private to the Scheduler's source files (scheduler*.cpp): the small
// helpers its sections share. Not part of the coordinator's interface.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

#include "common/farm/types.h"

namespace locus::farm::scheduler_detail {

inline double seconds(SteadyClock::duration d) { return std::chrono::duration<double>(d).count(); }

// A job's or worker's id: prefix and a number of at least 4 digits.
inline std::string numbered(const char* prefix, uint64_t n) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%s%04llu", prefix, static_cast<unsigned long long>(n));
  return buf;
}

inline std::string format_seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f s", s);
  return buf;
}

}  // namespace locus::farm::scheduler_detail
