// Linear float RGB images and their files: PNGs written by png.h, EXRs
// written and read by exr.h, TIFFs and every other read by the image plugin
// (image_plugin.h).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/base/math.h"
#include "common/base/params.h"
#include "common/base/status.h"

namespace locus {

// Row-major, top row first, 3 floats (linear RGB) per pixel.
struct Image {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;

  Image() = default;
  Image(int w, int h) : width(w), height(h), rgb(static_cast<size_t>(w) * h * 3, 0.0f) {}
  float* pixel(int x, int y) { return &rgb[(static_cast<size_t>(y) * width + x) * 3]; }
  const float* pixel(int x, int y) const { return &rgb[(static_cast<size_t>(y) * width + x) * 3]; }
};

// The one pixel store of the renderer's row loops (local, multi-scanned and
// ray-traced rows): frame pixel (x, y) of `band` goes to row y - band.y0 of
// the band's image, each channel rounded to float, unclamped (an EXR keeps
// the linear radiance; 8-bit and 16-bit outputs clamp when written).
inline void store_pixel(Image& band_pixels, const Band& band, int x, int y, const Color& c) {
  float* px = band_pixels.pixel(x, y - band.y0);
  px[0] = static_cast<float>(c.x);
  px[1] = static_cast<float>(c.y);
  px[2] = static_cast<float>(c.z);
}

// How write_image stores an image's samples, by the file's extension (any
// case): the one place that maps extensions to sample types, so that what a
// farm worker sends for a job (common/farm/band_codec.h) is what is written.
enum class SampleFormat { kUnsupported, kUint8, kUint16, kFloat32 };
SampleFormat output_sample_format(const std::string& path);
// A path's extension with its dot, lower case ("a/B.PNG" -> ".png"; "" if none).
std::string lower_extension(std::string_view path);

// Writes by extension: .png (8-bit, round(255 * clamp(v, 0, 1)), no transfer
// curve), .exr (float, linear, unclamped), .tif (16-bit). SHADING.md "Output".
// A PNG is tagged linear (gAMA 1.0), which is what its values are; with
// `for_display` it is tagged sRGB instead, so that a browser shows the
// stored values as they are (the dashboard's copies; same pixel values).
// PNGs are deflated at level kPngLevel (docs/farm.md "Frames": 3, not libpng's
// 6: a third less time per frame for 6-23% more bytes; the farm's
// coordinator encodes the frames it does not join from png8+deflate bands).
inline constexpr int kPngLevel = 3;
Status write_image(const std::string& path, const Image& image, bool for_display = false);
Result<Image> read_image(const std::string& path);
// `bytes` (an image already encoded) as the file `path`, replacing it.
Status write_file(const std::string& path, std::string_view bytes);

// 8-bit quantisation used by every 8-bit output (SHADING.md "Output").
inline int quantize8(float v) {
  const float c = !(v > 0.0f) ? 0.0f : (v > 1.0f ? 1.0f : v);
  return static_cast<int>(c * 255.0f + 0.5f);
}
// 16-bit quantisation of the 16-bit outputs (.tif), the same rounding.
inline int quantize16(float v) {
  const float c = !(v > 0.0f) ? 0.0f : (v > 1.0f ? 1.0f : v);
  return static_cast<int>(c * 65535.0f + 0.5f);
}

}  // namespace locus
