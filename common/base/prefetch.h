// Asking the memory for a cache line ahead of its use, where the use is
// known early and its address is scattered (docs/renderer.md, "Session 42").
#pragma once

namespace locus {

// Prefetches the cache line holding `p` (for reading, kept in every cache
// level). GCC deletes a loop whose only statements are __builtin_prefetch,
// as having no effect; the empty volatile asm that takes the address keeps
// the loop and costs nothing else.
inline void prefetch(const void* p) {
  __builtin_prefetch(p);
  asm volatile("" : : "r"(p));
}

}  // namespace locus
