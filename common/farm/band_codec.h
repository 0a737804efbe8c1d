// A band's pixels as they travel from a worker to the coordinator, in the
// encoding the job's output file needs (issue #25 item 4): only what the
// written frame keeps, so that the stitched frame is bit-identical to one
// written from the renderer's floats, in fewer bytes.
//
//   output      written as (common/base/image.h)   encoding       bytes/pixel
//   .png        8-bit, quantize8                   png8+deflate   3 before deflate
//               (a worker that does not offer it)  rgb8+zstd      3 before zstd
//   .tif .tiff  16-bit, quantize16                 rgb16+zstd     6 before zstd
//   .exr        float32, unclamped                 exr+zip        12 before zip
//               (a worker that does not offer it)  float32+zstd   12 before zstd
//   other       (none: a movie job has no bands)   float32        12
//
// The integer encodings carry the very code value the writer would store;
// decoding gives the float code/255 (code/65535), which the writer maps back
// to the same code (tests/farm/band_codec_test.cpp checks every code). The
// float encoding carries the floats' bits. Before zstd, samples of 2 and 4
// bytes are filtered: each is replaced by its difference (modulo 2^16 or
// 2^32) from the same channel of the pixel to its left, and the bytes are
// shuffled into planes, most significant byte first, one channel after
// another, where runs and small differences compress (docs/farm.md "Band
// encodings" has the measurements). Plain float32 is today's `repeated
// float rgb` of the wire, kept for workers and coordinators of older
// releases.
//
// png8+deflate is the 8-bit codes as a PNG file's image data holds them, so
// that the coordinator writes the frame's PNG from its bands' bytes without
// decoding or compressing anything (png_from_bands; docs/farm.md "Frames"):
// each row a PNG filter byte and the row's filtered bytes (the band's first
// row Sub, which looks only left, the others Up), raw-deflated at level 1
// (zlib) as one stream that ends with a sync flush (byte-aligned, not the
// last block), after the adler-32 of the filtered bytes (4 bytes, most
// significant first). Concatenated in row order, the bands' streams are the
// frame's: a PNG decoder reads each band's first row against the previous
// band's last row only through filters that do not look up, which is why
// decode_band refuses any other filter there.
//
// exr+zip is the same for EXR frames (exr_blocks_from_bands): the band's
// rows in the frame's blocks of 16 (common/base/exr.h), each block the band
// holds whole compressed as the EXR file stores it (exr_zip_block), and the
// rows of a block it shares with a neighbour (at most one above and one
// below) as float32+zstd, for the coordinator to compress that block from
// both bands' rows. Its bytes: big-endian uint32s head rows, blocks, tail
// rows; each block's rows and byte count, then its bytes; the byte count of
// the head rows' float32+zstd, then those bytes; the same for the tail.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/cost.h"
#include "common/base/labels.h"
#include "common/base/status.h"

namespace locus::farm {

// The values are those of v1::BandEncoding (proto/locus.proto).
enum class BandEncoding : int32_t {
  kFloat32 = 0,
  kRgb8Zstd = 1,
  kRgb16Zstd = 2,
  kFloat32Zstd = 3,
  kPng8Deflate = 4,
  kExrZip = 5
};
inline constexpr Labels<BandEncoding, 6> kBandEncodingLabels = {
    {{BandEncoding::kFloat32, "float32"},
     {BandEncoding::kRgb8Zstd, "rgb8+zstd"},
     {BandEncoding::kRgb16Zstd, "rgb16+zstd"},
     {BandEncoding::kFloat32Zstd, "float32+zstd"},
     {BandEncoding::kPng8Deflate, "png8+deflate"},
     {BandEncoding::kExrZip, "exr+zip"}}};

// A band's pixels in an encoding: `width` x `rows` pixels, 3 channels,
// row-major from the band's first row.
struct EncodedBand {
  BandEncoding encoding = BandEncoding::kFloat32;
  int width = 0;
  int rows = 0;
  std::string bytes;
};

// The most bytes a band decodes to (its floats): what one message could
// carry as floats before encodings existed, so every band that could travel
// then decodes now, and no payload makes the coordinator allocate more.
inline constexpr int64_t kMaxDecodedBandBytes = 64 << 20;

// The encoding for a job whose frames are written to `output` (a file name
// or pattern, e.g. "out/shot_####.png"), by output_sample_format; for an
// 8-bit output png8+deflate when the worker offers it (`png_deflate`,
// RegisterRequest.encodings), rgb8+zstd otherwise; for an EXR output
// exr+zip when the worker offers it (`exr_zip`), float32+zstd otherwise.
BandEncoding band_encoding_for(const std::string& output, bool png_deflate = false,
                               bool exr_zip = false);

// Whether rows [y0, y1) of a frame of `height` rows hold a whole block of
// the frame's EXR (kExrZipBlockRows rows, or the frame's last): exr+zip is
// leased only for such bands. A frame with a band that holds none (more
// bands than blocks) is stitched and written by write_exr, its blocks
// compressed on the coordinator's cores.
bool holds_exr_block(int y0, int y1, int height);

// `rgb` (width * rows * 3 linear floats, as render_band gives them) in
// `encoding`; exr+zip also needs the band's first row `y0` in a frame of
// `height` rows (0: the band ends the frame). InvalidArgument for a size
// that is not width x rows, rows outside the frame or an unknown encoding.
Result<EncodedBand> encode_band(BandEncoding encoding, int width, int rows,
                                const std::vector<float>& rgb, int y0 = 0, int height = 0);

// The floats of an encoded band: exactly its floats for float32 and
// float32+zstd, the codes as floats for the others (see above).
// InvalidArgument naming the problem for an unknown encoding, a size out of
// range, bytes of the wrong length for width x rows, and a zstd payload that
// is corrupt, truncated or claims another size; decompression never writes
// past the size width x rows needs.
Result<std::vector<float>> decode_band(const EncodedBand& band);

// What decode_band checks, without making the floats: Ok exactly when
// decode_band would decode the band. The coordinator checks a result on
// arrival with it, and keeps the bytes as they came.
Status check_band(const EncodedBand& band);

// The PNG file (8-bit RGB, tagged linear as write_image tags it) of a
// `width` x `height` frame whose bands, top to bottom, are all png8+deflate
// and were each accepted by decode_band: the file's image data is the
// bands' deflate streams joined, so nothing is decompressed or compressed
// again. InvalidArgument when a band is of another encoding or width, or
// the bands' rows do not add up to the height.
Result<std::string> png_from_bands(int width, int height, const std::vector<EncodedBand>& bands);

// The chunk data of every block of an EXR frame, top to bottom, for
// write_exr_blocks (common/base/exr.h): `blocks[k]` views either a band's
// own bytes (a block the band holds whole, as it came) or `made` (a block
// across bands, compressed from their edge rows). The views into the bands
// are valid while the bands are.
struct ExrFrameBlocks {
  std::vector<std::string_view> blocks;
  std::vector<std::string> made;
};

// The blocks of a `width` x `height` EXR frame from its bands, top to
// bottom, all exr+zip and each accepted by decode_band, band b starting at
// row y0s[b]; no block a band holds whole is copied. InvalidArgument when
// a band is of another encoding or width, its rows are not where y0s puts
// them, or they do not add up to the height.
Result<ExrFrameBlocks> exr_blocks_from_bands(int width, int height, const std::vector<int>& y0s,
                                             const std::vector<EncodedBand>& bands);

// A band's work per pixel (common/base/cost.h; docs/cost-map.md), as a
// worker returns it with the band's pixels when the job makes cost maps
// (CompleteBandRequest.cost) and the coordinator keeps it in the band's
// record: the five counts of every pixel as little-endian uint32 planes
// (all pixels' eye rays, then reflected, refracted, shadow rays, volume
// tests), then one byte of flags a pixel (1 traced, 2 in a ray-traced
// span), zstd-compressed. InvalidArgument for a buffer of no pixels.
Result<std::string> encode_band_cost(const CostBuffer& cost);
// The counts' bytes a pixel before zstd.
inline constexpr int kCostCountBytes = 21;
// The cost buffer of rows [y0, y1) of a `width`-pixel-wide frame from those
// bytes. InvalidArgument naming the problem for a size out of range, a
// payload that is not a zstd frame of exactly the size the rows need
// (nothing larger is allocated), or unknown flags.
Result<CostBuffer> decode_band_cost(std::string_view bytes, int width, int y0, int y1);
// What decode_band_cost checks of the bytes' size and compression, for a
// band of `pixels` pixels, without making the buffer (the coordinator's
// check on arrival).
Status check_band_cost(std::string_view bytes, int64_t pixels);

}  // namespace locus::farm
