// Broken invariants, as opposed to user errors (pbrt's CHECK against its
// error reporting): a bound that only a comment would otherwise protect (a
// fixed traversal stack, an index) is checked in every build type, Release
// included, and aborts naming the file, the line and the condition. User
// errors never come here: they are a Status naming the input (status.h).
#pragma once

#include <cstdio>
#include <cstdlib>

namespace locus::detail {
[[noreturn]] inline void check_failed(const char* file, int line, const char* condition) {
  std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", file, line, condition);
  std::abort();
}
}  // namespace locus::detail

#define LOCUS_CHECK(condition)                                       \
  do {                                                               \
    if (__builtin_expect(!(condition), 0)) {                         \
      ::locus::detail::check_failed(__FILE__, __LINE__, #condition); \
    }                                                                \
  } while (false)
