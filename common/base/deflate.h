// zlib streams (RFC 1950) made and read by libdeflate (Debian's
// libdeflate0): the format zlib makes, about as small at the same level, in
// about half the time. For whole buffers: the EXR blocks (exr.cpp) and a
// PNG frame's image data (png.cpp). PNG bands, whose streams end in a sync
// flush so that a frame can join them, keep zlib (band_codec.cpp).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace locus {

// `data` as one zlib stream at `level` (0-12; zlib's 1-9 mean about the
// same); empty when no compressor could be made (no memory).
std::string zlib_compress(std::string_view data, int level);

// The bytes of the zlib stream `z` into `out`, which holds exactly `n`:
// kOk only when the stream is intact (its adler-32 checked), makes exactly
// `n` bytes and is all of `z`. Never writes past `n`.
struct Inflated {
  enum Outcome { kOk, kCorrupt, kTooLong, kShort, kTrailing, kNoMemory } outcome = kOk;
  size_t made = 0;      // bytes made (kShort)
  size_t trailing = 0;  // bytes of `z` after the stream (kTrailing)
};
Inflated zlib_inflate(std::string_view z, void* out, size_t n);

}  // namespace locus
