// A band's pixels as they travel from a worker to the coordinator, in the
// encoding the job's output file needs (issue #25 item 4): only what the
// written frame keeps, so that the stitched frame is bit-identical to one
// written from the renderer's floats, in fewer bytes.
//
//   output      written as (common/base/image.h)   encoding       bytes/pixel
//   .png        8-bit, quantize8                   png8+deflate   3 before deflate
//               (a worker that does not offer it)  rgb8+zstd      3 before zstd
//   .tif .tiff  16-bit, quantize16                 rgb16+zstd     6 before zstd
//   .exr        float32, unclamped                 float32+zstd   12 before zstd
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
  kPng8Deflate = 4
};
inline constexpr Labels<BandEncoding, 5> kBandEncodingLabels = {
    {{BandEncoding::kFloat32, "float32"},
     {BandEncoding::kRgb8Zstd, "rgb8+zstd"},
     {BandEncoding::kRgb16Zstd, "rgb16+zstd"},
     {BandEncoding::kFloat32Zstd, "float32+zstd"},
     {BandEncoding::kPng8Deflate, "png8+deflate"}}};

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
// RegisterRequest.encodings), rgb8+zstd otherwise.
BandEncoding band_encoding_for(const std::string& output, bool png_deflate = false);

// `rgb` (width * rows * 3 linear floats, as render_band gives them) in
// `encoding`. InvalidArgument for a size that is not width x rows or an
// unknown encoding.
Result<EncodedBand> encode_band(BandEncoding encoding, int width, int rows,
                                const std::vector<float>& rgb);

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
