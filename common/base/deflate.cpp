#include "common/base/deflate.h"

#include <libdeflate.h>

#include <map>
#include <memory>

namespace locus {
namespace {

// libdeflate's compressors and decompressors may not be shared between
// threads: each thread keeps its own, made on first use (a compressor for
// each level it has used).
struct FreeCompressor {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};
struct FreeDecompressor {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

libdeflate_compressor* compressor(int level) {
  thread_local std::map<int, std::unique_ptr<libdeflate_compressor, FreeCompressor>> mine;
  auto& c = mine[level];
  if (!c) c.reset(libdeflate_alloc_compressor(level));
  return c.get();
}

libdeflate_decompressor* decompressor() {
  thread_local std::unique_ptr<libdeflate_decompressor, FreeDecompressor> mine;
  if (!mine) mine.reset(libdeflate_alloc_decompressor());
  return mine.get();
}

}  // namespace

std::string zlib_compress(std::string_view data, int level) {
  libdeflate_compressor* c = compressor(level);
  if (!c) return {};
  std::string z(libdeflate_zlib_compress_bound(c, data.size()), '\0');
  const size_t size = libdeflate_zlib_compress(c, data.data(), data.size(), z.data(), z.size());
  z.resize(size);  // 0: did not fit the bound, which cannot happen
  return z;
}

Inflated zlib_inflate(std::string_view z, void* out, size_t n) {
  Inflated r;
  libdeflate_decompressor* d = decompressor();
  if (!d) {
    r.outcome = Inflated::kNoMemory;
    return r;
  }
  size_t used = 0;
  const libdeflate_result e =
      libdeflate_zlib_decompress_ex(d, z.data(), z.size(), out, n, &used, &r.made);
  if (e == LIBDEFLATE_INSUFFICIENT_SPACE) {
    r.outcome = Inflated::kTooLong;
  } else if (e != LIBDEFLATE_SUCCESS) {
    r.outcome = Inflated::kCorrupt;
  } else if (r.made != n) {
    r.outcome = Inflated::kShort;
  } else if (used != z.size()) {
    r.outcome = Inflated::kTrailing;
    r.trailing = z.size() - used;
  }
  return r;
}

}  // namespace locus
