// EXR files of linear float RGB, through OpenEXR itself (a dozen shared
// libraries, loaded at start in a few milliseconds) rather than the image
// plugin's OpenImageIO (~250, half a second): every EXR frame a render, a
// worker farm or the coordinator writes, and every EXR the dashboard reads.
// docs/architecture.md "Image files".
#pragma once

#include <string>

#include "common/base/image.h"
#include "common/base/status.h"

namespace locus {

// Three 32-bit float channels R, G, B, unclamped, ZIP-compressed (lossless;
// SHADING.md "Output").
Status write_exr(const std::string& path, const Image& image);

// The R, G and B channels of an EXR file (half, float or uint) as floats,
// its data window's pixels, top row first.
Result<Image> read_exr(const std::string& path);

// Whether `path` starts with EXR's magic number (a missing or short file:
// false).
bool is_exr_file(const std::string& path);

}  // namespace locus
