// The extension -> sample type mapping of image.h, apart from image.cpp so
// that a binary which only needs the mapping (locus-worker, through
// common/farm/band_codec.cpp) does not link OpenImageIO's writer and the
// ~250 shared libraries it loads.
#include <algorithm>
#include <cctype>
#include <filesystem>

#include "common/base/image.h"

namespace locus {

std::string lower_extension(std::string_view path) {
  std::string ext = std::filesystem::path(std::string(path)).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

SampleFormat output_sample_format(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") return SampleFormat::kUint8;
  if (ext == ".exr") return SampleFormat::kFloat32;
  if (ext == ".tif" || ext == ".tiff") return SampleFormat::kUint16;
  return SampleFormat::kUnsupported;
}

}  // namespace locus
