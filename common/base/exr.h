// EXR files of linear float RGB, through OpenEXR itself (a dozen shared
// libraries, loaded at start in a few milliseconds) rather than the image
// plugin's OpenImageIO (~250, half a second): every EXR frame a render, a
// worker farm or the coordinator writes, and every EXR the dashboard reads.
// docs/architecture.md "Image files".
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/base/image.h"
#include "common/base/status.h"

namespace locus {

// Three 32-bit float channels R, G, B, unclamped, ZIP-compressed (lossless;
// SHADING.md "Output"): the frame's blocks compressed side by side
// (exr_zip_block, on up to 8 threads) and written by write_exr_blocks, so
// that a farm's frame joined from its bands' blocks is this very file.
Status write_exr(const std::string& path, const Image& image);

// The R, G and B channels of an EXR file (half, float or uint) as floats,
// its data window's pixels, top row first.
Result<Image> read_exr(const std::string& path);

// ---- Frames joined from blocks compressed elsewhere (docs/farm.md
// "Frames"): a farm's workers compress the blocks of their bands, and the
// coordinator writes the frame's file from those bytes.

// The scanlines of one block of a ZIP-compressed EXR: block k holds rows
// 16k to 16k + 15 (the last block of a frame may hold fewer).
inline constexpr int kExrZipBlockRows = 16;

// The chunk data of one block of a ZIP-compressed EXR (OpenEXR's
// ZIP_COMPRESSION, as write_exr writes): `rows` rows (1 to
// kExrZipBlockRows) of `width` pixels of interleaved RGB floats, as Image
// holds them, laid out as EXR stores a scanline block (each line's B, G
// and R samples, little-endian), its bytes split into halves and
// differenced, then compressed as a zlib stream at OpenEXR's default
// level (4; by libdeflate, in about half zlib's time); the block
// as laid out where that is not smaller (an EXR reader tells the two apart
// by the size).
std::string exr_zip_block(const float* rgb, int width, int rows);

// The inverse of exr_zip_block: the block's floats into `rgb` (width *
// rows * 3; null: only the check). InvalidArgument, naming `what`, for data
// that is neither the laid-out block nor a zlib stream of exactly its size.
Status exr_unzip_block(std::string_view data, int width, int rows, float* rgb,
                       const std::string& what);

// A `width` x `height` EXR like write_exr's from its blocks' chunk data,
// top to bottom (exr_zip_block's, one for each kExrZipBlockRows rows),
// written through OpenEXR's core library as they are: nothing is
// compressed here. InvalidArgument when the number of blocks is not the
// height's.
Status write_exr_blocks(const std::string& path, int width, int height,
                        const std::vector<std::string_view>& blocks);

// Whether `path` starts with EXR's magic number (a missing or short file:
// false).
bool is_exr_file(const std::string& path);

}  // namespace locus
