// The image plugin: the TIFF writer and the reader of every image that
// is no EXR (exr.h does those), in a shared library of its own,
// liblocus-image-io.so (common/base/image_plugin/oiio.cpp), the one part of
// Locus that links OpenImageIO. OpenImageIO brings about 250 shared
// libraries (OpenCV, FFmpeg, GDAL, ...): linked into a binary they cost
// each start of `locus` and `locus-coordinator` half a second in the
// dynamic loader, whether it touches an image or not. image.cpp loads the
// plugin on its first TIFF or such a read, from <the executable's
// directory>/../lib/locus/ (the build tree and the installed package
// alike). docs/architecture.md "Image files".
#pragma once

#include <cstdint>
#include <string>

#include "common/base/image.h"

namespace locus {

// Raised when the table's layout or meaning changes: a plugin of another
// build is refused by name, not called.
inline constexpr int kImagePluginAbi = 2;
inline constexpr const char* kImagePluginFile = "liblocus-image-io.so";
inline constexpr const char* kImagePluginEntry = "locus_image_plugin";

struct ImagePlugin {
  int abi = kImagePluginAbi;
  // Writes width x height RGB 16-bit `samples` (quantize16) to `path`, a
  // TIFF; false with *error on failure.
  bool (*write16)(const char* path, int width, int height, const uint16_t* samples,
                  std::string* error) = nullptr;
  // Reads the first three channels of `path` as floats (8-bit files: code
  // / 255) into *image. 0: read; 1: cannot open it; 2: it is no RGB
  // image, or it does not decode. *error says which and why.
  int (*read)(const char* path, Image* image, std::string* error) = nullptr;
};

}  // namespace locus

// The plugin's one exported symbol (kImagePluginEntry).
extern "C" const locus::ImagePlugin* locus_image_plugin();
