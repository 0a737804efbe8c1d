// PNG files of 8-bit RGB, made here (PNG specification, ISO/IEC
// 15948; zlib and deflate streams, RFC 1950 and 1951): every PNG Locus
// writes, a single-process render's (write_image) and a frame the farm's
// coordinator joins from its bands' deflate streams (common/farm/
// band_codec.h, png_from_bands). Writing a PNG loads no OpenImageIO
// (docs/architecture.md "Image files").
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/image.h"
#include "common/base/status.h"

namespace locus {

// PNG's row filters (PNG specification, 9.2).
enum PngFilter : unsigned char {
  kPngFilterNone = 0,
  kPngFilterSub = 1,
  kPngFilterUp = 2,
  kPngFilterAverage = 3,
  kPngFilterPaeth = 4
};

// Bytes of one filtered row: the filter byte, then 3 bytes a pixel.
inline size_t png_row_bytes(int width) { return 1 + static_cast<size_t>(width) * 3; }

// PNG's and zlib's integers: 32 bits, big-endian.
void put_be32(std::string& out, uint32_t v);
uint32_t get_be32(const char* p);

// `rows` rows of `width` pixels (rgb: width * rows * 3 floats) as a PNG's
// image data holds them before compression: each row a filter byte, then
// its codes (quantize8, SHADING.md "Output") filtered, the first row Sub,
// the others Up.
std::string png_filter_rows(int width, int rows, const std::vector<float>& rgb);

// What a PNG says its samples are: linear (gAMA 1.0: they are the
// radiance, clamped and quantised) or for display (sRGB: a browser shows
// the stored values as they are; the dashboard's copies).
enum class PngTag { kLinear, kDisplay };

// A PNG file of 8-bit RGB: the signature, IHDR, the tag, then one IDAT
// chunk for each of `idat`, which together hold the zlib stream of the
// filtered rows, then IEND.
std::string png_file(int width, int height, PngTag tag, const std::vector<std::string_view>& idat);

// `image` as a PNG file's bytes, its rows filtered by png_filter_rows and
// deflated at level `level` in one IDAT, by libdeflate (deflate.h).
Result<std::string> encode_png(const Image& image, PngTag tag, int level = kPngLevel);

}  // namespace locus
