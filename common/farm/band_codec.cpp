#include "common/farm/band_codec.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string_view>

#include "common/base/check.h"
#include "common/base/exr.h"
#include "common/base/image.h"
#include "common/base/png.h"

namespace locus::farm {
namespace {

// zstd's default level: at 256x256 a band compresses in a few milliseconds,
// next to its render's tenths of a second to tens of seconds.
constexpr int kZstdLevel = 3;

struct Layout {
  int sample_bytes = 0;  // bytes of one channel of one pixel
  bool zstd = false;
};

// Nothing for an encoding the table does not name (from a newer or broken
// peer).
std::optional<Layout> layout_of(BandEncoding e) {
  switch (e) {
    case BandEncoding::kFloat32:
      return Layout{4, false};
    case BandEncoding::kRgb8Zstd:
      return Layout{1, true};
    case BandEncoding::kRgb16Zstd:
      return Layout{2, true};
    case BandEncoding::kFloat32Zstd:
      return Layout{4, true};
    case BandEncoding::kPng8Deflate:
    case BandEncoding::kExrZip:
      break;  // not samples in a layout: png8_codes, exr_zip_floats
  }
  return std::nullopt;
}

std::string encoding_name(BandEncoding e) {
  std::string name(label_name(kBandEncodingLabels, e, ""));
  if (name.empty()) name = "unknown encoding " + std::to_string(static_cast<int32_t>(e));
  return name;
}

// The samples (code values, or the floats' bits) of one encoding.
uint32_t sample_of(BandEncoding e, float v) {
  switch (e) {
    case BandEncoding::kRgb8Zstd:
      return static_cast<uint32_t>(quantize8(v));
    case BandEncoding::kRgb16Zstd:
      return static_cast<uint32_t>(quantize16(v));
    default:
      return std::bit_cast<uint32_t>(v);
  }
}
// The float the writer maps back to the sample (code / 255 is the float
// whose quantize8 is the code; tests/farm/band_codec_test.cpp checks all).
float float_of(BandEncoding e, uint32_t s) {
  switch (e) {
    case BandEncoding::kRgb8Zstd:
      return static_cast<float>(s) / 255.0f;
    case BandEncoding::kRgb16Zstd:
      return static_cast<float>(s) / 65535.0f;
    default:
      return std::bit_cast<float>(s);
  }
}

// Samples to bytes. Multi-byte samples of a compressed encoding are
// filtered (header comment): differences from the pixel to the left, bytes
// in planes. Otherwise little-endian, in pixel order.
std::string pack(const std::vector<uint32_t>& samples, Layout l) {
  const size_t n = samples.size();
  const size_t pixels = n / 3;
  std::string out(n * l.sample_bytes, '\0');
  if (!l.zstd || l.sample_bytes == 1) {
    for (size_t i = 0; i < n; ++i) {
      for (int b = 0; b < l.sample_bytes; ++b)
        out[i * l.sample_bytes + b] = static_cast<char>(samples[i] >> (8 * b));
    }
    return out;
  }
  size_t k = 0;
  for (int b = l.sample_bytes - 1; b >= 0; --b) {
    for (size_t c = 0; c < 3; ++c) {
      uint32_t left = 0;
      for (size_t p = 0; p < pixels; ++p) {
        const uint32_t s = samples[p * 3 + c];
        out[k++] = static_cast<char>((s - left) >> (8 * b));
        left = s;
      }
    }
  }
  return out;
}

// The inverse of pack(); `bytes` holds exactly n * sample_bytes.
std::vector<uint32_t> unpack(const std::string& bytes, size_t n, Layout l) {
  std::vector<uint32_t> samples(n, 0);
  const auto byte = [&](size_t i) {
    return static_cast<uint32_t>(static_cast<unsigned char>(bytes[i]));
  };
  if (!l.zstd || l.sample_bytes == 1) {
    for (size_t i = 0; i < n; ++i) {
      for (int b = 0; b < l.sample_bytes; ++b)
        samples[i] |= byte(i * l.sample_bytes + b) << (8 * b);
    }
    return samples;
  }
  const size_t pixels = n / 3;
  size_t k = 0;
  for (int b = l.sample_bytes - 1; b >= 0; --b) {
    for (size_t c = 0; c < 3; ++c) {
      for (size_t p = 0; p < pixels; ++p) samples[p * 3 + c] |= byte(k++) << (8 * b);
    }
  }
  // Differences back to samples, modulo the sample's width.
  const uint32_t mask = l.sample_bytes == 4 ? 0xffffffffu : (1u << (8 * l.sample_bytes)) - 1;
  for (size_t i = 3; i < n; ++i) samples[i] = (samples[i] + samples[i - 3]) & mask;
  return samples;
}

std::string band_size_text(int width, int rows) {
  std::string s = std::to_string(width);
  s.append(" x ").append(std::to_string(rows));
  return s;
}

// ---- png8+deflate (band_codec.h)

// zlib's fastest level: the worker pays it per pixel, next to about a
// microsecond of rendering per pixel (docs/farm.md "Frames" has the sizes).
constexpr int kDeflateLevel = 1;

Result<std::string> deflate_rows(const std::string& raw) {
  z_stream z{};
  if (deflateInit2(&z, kDeflateLevel, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    return Internal("zlib: cannot start deflate");
  std::string out;
  put_be32(out, static_cast<uint32_t>(
                    adler32(1, reinterpret_cast<const Bytef*>(raw.data()), static_cast<uInt>(raw.size()))));
  // deflateBound is for a finished stream; a sync flush adds a few bytes.
  out.resize(4 + deflateBound(&z, raw.size()) + 64);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(raw.data()));
  z.avail_in = static_cast<uInt>(raw.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data() + 4);
  z.avail_out = static_cast<uInt>(out.size() - 4);
  const int r = deflate(&z, Z_SYNC_FLUSH);
  const bool whole = r == Z_OK && z.avail_in == 0 && z.avail_out > 0;
  out.resize(4 + z.total_out);
  deflateEnd(&z);
  if (!whole) return Internal("zlib: deflate did not take the whole band");
  return out;
}

// The filtered rows of a png8+deflate band (a filter byte, then the row),
// after every check decode_band makes; `what` names the band in errors.
Result<std::string> png8_rows(const EncodedBand& band, const std::string& what) {
  const size_t row_bytes = png_row_bytes(band.width);
  const size_t expected = row_bytes * band.rows;
  if (band.bytes.size() < 4) return InvalidArgument(what + ": no adler-32 before the rows");
  std::string raw(expected, '\0');
  z_stream z{};
  if (inflateInit2(&z, -15) != Z_OK) return Internal("zlib: cannot start inflate");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(band.bytes.data() + 4));
  z.avail_in = static_cast<uInt>(band.bytes.size() - 4);
  z.next_out = reinterpret_cast<Bytef*>(raw.data());
  z.avail_out = static_cast<uInt>(expected);
  const int r = inflate(&z, Z_SYNC_FLUSH);
  const uLong got = z.total_out;
  const uInt left = z.avail_in;
  // Where the stream stopped: waiting for a block header (128), on a byte
  // boundary (no bits left, & 63), not after a last block (64): so the next
  // band's stream can follow it in the frame's.
  const int state = z.data_type;
  inflateEnd(&z);
  if (r == Z_STREAM_END)
    return InvalidArgument(what + ": the deflate stream ends with the last block (a band's must not: "
                                  "the frame's continues)");
  if (r != Z_OK && r != Z_BUF_ERROR) return InvalidArgument(what + ": corrupt deflate stream");
  if (got != expected || left != 0) {
    std::string m = what;
    m.append(": the deflate stream holds ").append(left != 0 ? "more than " : "");
    m.append(std::to_string(got)).append(" bytes, expected ").append(std::to_string(expected));
    return InvalidArgument(m);
  }
  if ((state & (64 | 128 | 63)) != 128)
    return InvalidArgument(what + ": the deflate stream does not end on a sync flush");
  if (adler32(1, reinterpret_cast<const Bytef*>(raw.data()), static_cast<uInt>(raw.size())) !=
      get_be32(band.bytes.data()))
    return InvalidArgument(what + ": the rows do not match their adler-32");
  for (int y = 0; y < band.rows; ++y) {
    const auto filter = static_cast<unsigned char>(raw[y * row_bytes]);
    if (filter > kPngFilterPaeth || (y == 0 && filter > kPngFilterSub)) {
      std::string m = what;
      m.append(": row ").append(std::to_string(y)).append(" has filter ");
      m.append(std::to_string(filter)).append(y == 0 ? " (the first row: 0 or 1)" : " (0 to 4)");
      return InvalidArgument(m);
    }
  }
  return raw;
}

// The codes of filtered rows that png8_rows accepted: unfiltered (PNG
// specification, 9.2), bytes per pixel 3.
std::vector<unsigned char> png8_codes(const std::string& raw, int width, int rows) {
  const size_t row_bytes = png_row_bytes(width);
  const size_t stride = static_cast<size_t>(width) * 3;
  std::vector<unsigned char> codes(stride * rows);
  for (int y = 0; y < rows; ++y) {
    const auto* in = reinterpret_cast<const unsigned char*>(raw.data()) + y * row_bytes;
    const unsigned char filter = in[0];
    unsigned char* out = codes.data() + y * stride;
    const unsigned char* up = y > 0 ? out - stride : nullptr;
    for (size_t i = 0; i < stride; ++i) {
      const int a = i >= 3 ? out[i - 3] : 0;
      const int b = up ? up[i] : 0;
      const int c = up && i >= 3 ? up[i - 3] : 0;
      int pred = 0;
      switch (filter) {
        case kPngFilterNone: pred = 0; break;
        case kPngFilterSub: pred = a; break;
        case kPngFilterUp: pred = b; break;
        case kPngFilterAverage: pred = (a + b) / 2; break;
        default: {
          const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
          pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
        }
      }
      out[i] = static_cast<unsigned char>(in[1 + i] + pred);
    }
  }
  return codes;
}

// exr+zip's encoding (below, with its decoding).
Result<EncodedBand> encode_exr_zip(int width, int rows, const std::vector<float>& rgb, int y0,
                                   int height);

}  // namespace

BandEncoding band_encoding_for(const std::string& output, bool png_deflate, bool exr_zip) {
  switch (output_sample_format(output)) {
    case SampleFormat::kUint8:
      return png_deflate ? BandEncoding::kPng8Deflate : BandEncoding::kRgb8Zstd;
    case SampleFormat::kUint16:
      return BandEncoding::kRgb16Zstd;
    case SampleFormat::kFloat32:
      return exr_zip ? BandEncoding::kExrZip : BandEncoding::kFloat32Zstd;
    case SampleFormat::kUnsupported:
      break;
  }
  return BandEncoding::kFloat32;
}

Result<EncodedBand> encode_band(BandEncoding encoding, int width, int rows,
                                const std::vector<float>& rgb, int y0, int height) {
  const std::optional<Layout> l = layout_of(encoding);
  if (!l && encoding != BandEncoding::kPng8Deflate && encoding != BandEncoding::kExrZip)
    return InvalidArgument("cannot encode a band in " + encoding_name(encoding));
  if (width < 1 || rows < 1 || rgb.size() != static_cast<size_t>(width) * rows * 3) {
    std::string m = "cannot encode a band of ";
    m.append(band_size_text(width, rows)).append(" pixels from ");
    m.append(std::to_string(rgb.size())).append(" floats");
    return InvalidArgument(m);
  }
  if (encoding == BandEncoding::kExrZip) return encode_exr_zip(width, rows, rgb, y0, height);
  if (!l) {
    auto bytes = deflate_rows(png_filter_rows(width, rows, rgb));
    if (!bytes.ok()) return bytes.status();
    return EncodedBand{encoding, width, rows, std::move(*bytes)};
  }
  std::vector<uint32_t> samples(rgb.size());
  for (size_t i = 0; i < rgb.size(); ++i) samples[i] = sample_of(encoding, rgb[i]);
  EncodedBand out{encoding, width, rows, pack(samples, *l)};
  if (l->zstd) {
    std::string z(ZSTD_compressBound(out.bytes.size()), '\0');
    const size_t n =
        ZSTD_compress(z.data(), z.size(), out.bytes.data(), out.bytes.size(), kZstdLevel);
    if (ZSTD_isError(n)) return Internal(std::string("zstd: ") + ZSTD_getErrorName(n));
    z.resize(n);
    out.bytes = std::move(z);
  }
  return out;
}

namespace {

// A zstd frame that must inflate to exactly `expected` bytes, into `out`.
// The frame must say its size, and that size must be the expected one: a
// payload claiming more is refused before anything is allocated.
Status inflate_exactly(std::string_view bytes, size_t expected, const std::string& what,
                       std::string& out) {
  const unsigned long long claimed = ZSTD_getFrameContentSize(bytes.data(), bytes.size());
  if (claimed == ZSTD_CONTENTSIZE_ERROR || claimed == ZSTD_CONTENTSIZE_UNKNOWN) {
    return InvalidArgument(what + ": the payload is not a zstd frame with its size");
  }
  if (claimed != expected) {
    std::string m = what;
    m.append(": the zstd frame holds ").append(std::to_string(claimed));
    m.append(" bytes, expected ").append(std::to_string(expected));
    return InvalidArgument(m);
  }
  out.resize(expected);
  // Bounded by the destination's size, whatever the frames say.
  const size_t got = ZSTD_decompress(out.data(), out.size(), bytes.data(), bytes.size());
  if (ZSTD_isError(got)) {
    return InvalidArgument(what + ": corrupt or truncated zstd payload (" + ZSTD_getErrorName(got) +
                           ")");
  }
  if (got != expected) {
    std::string m = what;
    m.append(": the zstd payload holds ").append(std::to_string(got));
    m.append(" bytes, expected ").append(std::to_string(expected));
    return InvalidArgument(m);
  }
  return Status::Ok();
}

// Names a band in errors.
std::string band_text(const EncodedBand& band) {
  return encoding_name(band.encoding) + " band of " + band_size_text(band.width, band.rows) +
         " pixels";
}

// A band's size: at least a pixel, its floats at most kMaxDecodedBandBytes.
Status check_size(const EncodedBand& band, const std::string& what) {
  if (band.width < 1 || band.rows < 1 ||
      static_cast<int64_t>(band.width) * band.rows > kMaxDecodedBandBytes / 12) {
    std::string m = what;
    m.append(": the size is out of range (at most ");
    m.append(std::to_string(kMaxDecodedBandBytes / 12)).append(" pixels)");
    return InvalidArgument(m);
  }
  return Status::Ok();
}

// Every check decode_band makes, in one place. On success `inflated` holds
// the band's bytes when they were compressed (the samples as pack() laid
// them out, or png8+deflate's filtered rows); uncompressed float32 is
// band.bytes itself, and `inflated` stays empty. On failure `inflated`
// means nothing.
Status check_bytes(const EncodedBand& band, std::string& inflated) {
  const std::optional<Layout> l = layout_of(band.encoding);
  if (!l && band.encoding != BandEncoding::kPng8Deflate)
    return InvalidArgument("band pixels in " + encoding_name(band.encoding));
  const std::string what = band_text(band);
  if (Status s = check_size(band, what); !s.ok()) return s;
  const size_t n = static_cast<size_t>(band.width) * band.rows * 3;
  if (!l) {
    auto rows = png8_rows(band, what);
    if (!rows.ok()) return rows.status();
    inflated = std::move(*rows);
    return Status::Ok();
  }
  const size_t expected = n * l->sample_bytes;
  if (!l->zstd) {
    if (band.bytes.size() == expected) return Status::Ok();
    std::string m = what;
    m.append(": ").append(std::to_string(band.bytes.size())).append(" bytes, expected ");
    m.append(std::to_string(expected));
    return InvalidArgument(m);
  }
  return inflate_exactly(band.bytes, expected, what, inflated);
}

// ---- exr+zip (band_codec.h)

// Where the frame's blocks of kExrZipBlockRows fall in rows [y0, y1) of a
// frame of `height` rows: `head` rows before the first block the band holds
// whole, `blocks` such blocks, `tail` rows after them.
struct ExrSplit {
  int head = 0;
  int blocks = 0;
  int tail = 0;
};
ExrSplit exr_split(int y0, int y1, int height) {
  ExrSplit s;
  int y = (y0 + kExrZipBlockRows - 1) / kExrZipBlockRows * kExrZipBlockRows;
  if (y >= y1) {
    s.head = y1 - y0;
    return s;
  }
  s.head = y - y0;
  for (; y < y1 && std::min(y + kExrZipBlockRows, height) <= y1; y += kExrZipBlockRows) ++s.blocks;
  s.tail = y1 - std::min(y, y1);
  return s;
}

}  // namespace

bool holds_exr_block(int y0, int y1, int height) {
  return y0 >= 0 && y0 < y1 && y1 <= height && exr_split(y0, y1, height).blocks > 0;
}

namespace {

// The parts of an exr+zip band's bytes, as views into them.
struct ExrZipParts {
  ExrSplit split;
  std::vector<std::pair<int, std::string_view>> blocks;  // rows, chunk data
  std::string_view head, tail;                           // float32+zstd
};

void put_part(std::string& out, std::string_view bytes) {
  put_be32(out, static_cast<uint32_t>(bytes.size()));
  out.append(bytes);
}

Result<EncodedBand> encode_exr_zip(int width, int rows, const std::vector<float>& rgb, int y0,
                                   int height) {
  if (height == 0) height = y0 + rows;
  if (y0 < 0 || y0 + rows > height) {
    return InvalidArgument("cannot encode rows " + std::to_string(y0) + " to " +
                           std::to_string(y0 + rows - 1) + " of a frame of " +
                           std::to_string(height) + " rows");
  }
  const ExrSplit split = exr_split(y0, y0 + rows, height);
  const size_t row_floats = static_cast<size_t>(width) * 3;
  // Rows [from, from + n) of the band as float32+zstd; nothing for none.
  const auto edge = [&](int from, int n) -> Result<std::string> {
    if (n == 0) return std::string();
    const auto first = rgb.begin() + static_cast<ptrdiff_t>(from * row_floats);
    auto band =
        encode_band(BandEncoding::kFloat32Zstd, width, n,
                    std::vector<float>(first, first + static_cast<ptrdiff_t>(n * row_floats)));
    if (!band.ok()) return band.status();
    return std::move(band->bytes);
  };
  std::string out;
  put_be32(out, static_cast<uint32_t>(split.head));
  put_be32(out, static_cast<uint32_t>(split.blocks));
  put_be32(out, static_cast<uint32_t>(split.tail));
  int row = split.head;
  for (int b = 0; b < split.blocks; ++b) {
    const int n = std::min(kExrZipBlockRows, height - (y0 + row));
    put_be32(out, static_cast<uint32_t>(n));
    put_part(out, exr_zip_block(rgb.data() + row * row_floats, width, n));
    row += n;
  }
  auto head = edge(0, split.head);
  if (!head.ok()) return head.status();
  put_part(out, *head);
  auto tail = edge(row, split.tail);
  if (!tail.ok()) return tail.status();
  put_part(out, *tail);
  return EncodedBand{BandEncoding::kExrZip, width, rows, std::move(out)};
}

// The parts of an exr+zip band, their sizes checked against the band's
// rows (nothing decompressed).
Result<ExrZipParts> exr_zip_parts(const EncodedBand& band, const std::string& what) {
  if (Status s = check_size(band, what); !s.ok()) return s;
  std::string_view in(band.bytes);
  bool short_read = false;
  const auto u32 = [&]() -> uint32_t {
    if (in.size() < 4) {
      short_read = true;
      return 0;
    }
    const uint32_t v = get_be32(in.data());
    in.remove_prefix(4);
    return v;
  };
  const auto part = [&]() -> std::string_view {
    const uint32_t n = u32();
    if (short_read || n > in.size()) {
      short_read = true;
      return {};
    }
    std::string_view p = in.substr(0, n);
    in.remove_prefix(n);
    return p;
  };
  ExrZipParts p;
  const uint32_t head = u32(), blocks = u32(), tail = u32();
  if (short_read || head > static_cast<uint32_t>(band.rows) ||
      blocks > static_cast<uint32_t>(band.rows) || tail > static_cast<uint32_t>(band.rows))
    return InvalidArgument(what + ": its rows' layout is out of range");
  p.split = {static_cast<int>(head), static_cast<int>(blocks), static_cast<int>(tail)};
  int64_t rows = head + tail;
  for (uint32_t b = 0; b < blocks && !short_read; ++b) {
    const uint32_t n = u32();
    // Only the frame's last block is shorter, and nothing follows it.
    if (n < 1 || n > kExrZipBlockRows || (n < kExrZipBlockRows && (b + 1 < blocks || tail > 0)))
      return InvalidArgument(what + ": block " + std::to_string(b) + " of " + std::to_string(n) +
                             " rows");
    p.blocks.emplace_back(static_cast<int>(n), part());
    rows += n;
  }
  p.head = part();
  p.tail = part();
  if (short_read) return InvalidArgument(what + ": the bytes end inside a part");
  if (!in.empty()) return InvalidArgument(what + ": bytes after the last part");
  if (rows != band.rows) {
    return InvalidArgument(what + ": its parts hold " + std::to_string(rows) + " rows, expected " +
                           std::to_string(band.rows));
  }
  if (p.head.empty() != (head == 0) || p.tail.empty() != (tail == 0))
    return InvalidArgument(what + ": edge rows without their bytes, or bytes without rows");
  return p;
}

// An edge's float32+zstd rows into `out` (null: only checked).
Status edge_floats(std::string_view bytes, int width, int rows, float* out,
                   const std::string& what) {
  if (rows == 0) return Status::Ok();
  const EncodedBand edge{BandEncoding::kFloat32Zstd, width, rows, std::string(bytes)};
  if (!out) {
    const Status s = check_band(edge);
    return s.ok() ? s : Status(s.code(), what + ": " + s.message());
  }
  auto floats = decode_band(edge);
  if (!floats.ok()) return Status(floats.status().code(), what + ": " + floats.status().message());
  std::copy(floats->begin(), floats->end(), out);
  return Status::Ok();
}

// The floats of an exr+zip band into `out` (resized to width * rows * 3
// once exr_zip_parts has checked the size; null: only checked), after every
// check decode_band makes. The check inflates each block without
// rearranging its bytes into floats.
Status exr_zip_floats(const EncodedBand& band, std::vector<float>* out) {
  const std::string what = band_text(band);
  auto parts = exr_zip_parts(band, what);
  if (!parts.ok()) return parts.status();
  const size_t row_floats = static_cast<size_t>(band.width) * 3;
  float* rgb = nullptr;
  if (out) {
    out->assign(row_floats * band.rows, 0.0f);
    rgb = out->data();
  }
  const auto at = [&](size_t row) { return rgb ? rgb + row * row_floats : nullptr; };
  if (Status s = edge_floats(parts->head, band.width, parts->split.head, at(0), what + ", head");
      !s.ok())
    return s;
  size_t row = parts->split.head;
  for (size_t b = 0; b < parts->blocks.size(); ++b) {
    const auto& [n, data] = parts->blocks[b];
    if (Status s =
            exr_unzip_block(data, band.width, n, at(row), what + ", block " + std::to_string(b));
        !s.ok())
      return s;
    row += n;
  }
  return edge_floats(parts->tail, band.width, parts->split.tail, at(row), what + ", tail");
}

}  // namespace

Result<ExrFrameBlocks> exr_blocks_from_bands(int width, int height, const std::vector<int>& y0s,
                                             const std::vector<EncodedBand>& bands) {
  if (width < 1 || height < 1) return InvalidArgument("an EXR frame of no pixels");
  if (y0s.size() != bands.size()) return InvalidArgument("a first row for each band, expected");
  const size_t row_floats = static_cast<size_t>(width) * 3;
  const int count = (height + kExrZipBlockRows - 1) / kExrZipBlockRows;
  ExrFrameBlocks out;
  out.blocks.resize(count);
  std::vector<bool> whole(count, false);
  // The edge rows of every band, and which rows of the frame they are.
  std::vector<float> edges;
  std::vector<std::pair<int, size_t>> edge_rows;  // frame row, offset in edges
  int next = 0;
  for (size_t b = 0; b < bands.size(); ++b) {
    const EncodedBand& band = bands[b];
    const std::string what = "band " + std::to_string(b);
    if (band.encoding != BandEncoding::kExrZip || band.width != width || y0s[b] != next)
      return InvalidArgument(what + " is not an exr+zip band " + std::to_string(width) +
                             " pixels wide from row " + std::to_string(next));
    auto parts = exr_zip_parts(band, what);
    if (!parts.ok()) return parts.status();
    const ExrSplit split = exr_split(next, next + band.rows, height);
    if (next + band.rows > height || split.head != parts->split.head ||
        split.blocks != parts->split.blocks || split.tail != parts->split.tail)
      return InvalidArgument(what + ": its blocks are not where rows " + std::to_string(next) +
                             " to " + std::to_string(next + band.rows - 1) + " put them");
    const auto add_edge = [&](std::string_view bytes, int first, int n) -> Status {
      const size_t at = edges.size();
      edges.resize(at + n * row_floats);
      for (int r = 0; r < n; ++r) edge_rows.emplace_back(first + r, at + r * row_floats);
      return edge_floats(bytes, width, n, edges.data() + at, what);
    };
    if (Status s = add_edge(parts->head, next, split.head); !s.ok()) return s;
    int y = next + split.head;
    for (const auto& [n, data] : parts->blocks) {
      out.blocks[y / kExrZipBlockRows] = data;
      whole[y / kExrZipBlockRows] = true;
      y += n;
    }
    if (Status s = add_edge(parts->tail, y, split.tail); !s.ok()) return s;
    next += band.rows;
  }
  if (next != height) {
    return InvalidArgument("the bands hold " + std::to_string(next) + " rows of a frame of " +
                           std::to_string(height));
  }
  // The blocks across bands, from their rows (in frame order: the bands
  // cover the frame in order, so edge_rows is sorted).
  std::vector<float> block(row_floats * kExrZipBlockRows);
  // Reserved, so that out.made never moves its strings (a short one lives
  // inside its std::string) while earlier blocks view them.
  out.made.reserve(static_cast<size_t>(std::count(whole.begin(), whole.end(), false)));
  size_t e = 0;
  for (int k = 0; k < count; ++k) {
    if (whole[k]) continue;
    const int y = k * kExrZipBlockRows, n = std::min(kExrZipBlockRows, height - y);
    while (e < edge_rows.size() && edge_rows[e].first < y) ++e;
    for (int r = 0; r < n; ++r, ++e) {
      // Every row is in a whole block or an edge: the bands cover the frame.
      LOCUS_CHECK(e < edge_rows.size() && edge_rows[e].first == y + r);
      std::copy_n(edges.begin() + static_cast<ptrdiff_t>(edge_rows[e].second), row_floats,
                  block.begin() + static_cast<ptrdiff_t>(r * row_floats));
    }
    out.blocks[k] = out.made.emplace_back(exr_zip_block(block.data(), width, n));
  }
  return out;
}

Status check_band(const EncodedBand& band) {
  if (band.encoding == BandEncoding::kExrZip) return exr_zip_floats(band, nullptr);
  std::string inflated;
  return check_bytes(band, inflated);
}

Result<std::vector<float>> decode_band(const EncodedBand& band) {
  if (band.encoding == BandEncoding::kExrZip) {
    std::vector<float> rgb;
    if (Status s = exr_zip_floats(band, &rgb); !s.ok()) return s;
    return rgb;
  }
  std::string inflated;
  if (Status s = check_bytes(band, inflated); !s.ok()) return s;
  const size_t n = static_cast<size_t>(band.width) * band.rows * 3;
  std::vector<float> rgb(n);
  if (band.encoding == BandEncoding::kPng8Deflate) {
    const std::vector<unsigned char> codes = png8_codes(inflated, band.width, band.rows);
    for (size_t i = 0; i < n; ++i) rgb[i] = float_of(BandEncoding::kRgb8Zstd, codes[i]);
    return rgb;
  }
  const std::vector<uint32_t> samples =
      unpack(inflated.empty() ? band.bytes : inflated, n, *layout_of(band.encoding));
  std::string().swap(inflated);  // the largest band holds one copy less at a time
  for (size_t i = 0; i < n; ++i) rgb[i] = float_of(band.encoding, samples[i]);
  return rgb;
}

Result<std::string> png_from_bands(int width, int height, const std::vector<EncodedBand>& bands) {
  if (width < 1 || height < 1) return InvalidArgument("a PNG frame of no pixels");
  // The zlib stream: its header, each band's deflate bytes, an empty last
  // block, the adler-32 of all rows (RFC 1950, 1951).
  std::vector<std::string_view> idat;
  std::string first("\x78\x01", 2);
  uLong adler = 1;
  int rows = 0;
  for (size_t b = 0; b < bands.size(); ++b) {
    const EncodedBand& band = bands[b];
    if (band.encoding != BandEncoding::kPng8Deflate || band.width != width || band.rows < 1 ||
        band.bytes.size() < 4) {
      std::string m = "band ";
      m.append(std::to_string(b)).append(" is not a png8+deflate band ");
      m.append(std::to_string(width)).append(" pixels wide");
      return InvalidArgument(m);
    }
    rows += band.rows;
    adler = adler32_combine(adler, get_be32(band.bytes.data()),
                            static_cast<z_off_t>(png_row_bytes(width) * band.rows));
    const std::string_view stream = std::string_view(band.bytes).substr(4);
    if (b == 0) {
      first.append(stream);
      idat.emplace_back(first);
    } else {
      idat.push_back(stream);
    }
  }
  if (rows != height) {
    std::string m = "the bands hold ";
    m.append(std::to_string(rows)).append(" rows of a frame of ").append(std::to_string(height));
    return InvalidArgument(m);
  }
  std::string last("\x03\x00", 2);
  put_be32(last, static_cast<uint32_t>(adler));
  idat.emplace_back(last);
  return png_file(width, height, PngTag::kLinear, idat);
}

namespace {

// A cost buffer's planes: the five counts as little-endian uint32, each
// field's pixels together, then a byte of flags per pixel.
constexpr size_t kCostCounts = 5;
constexpr size_t kCostBytesPerPixel = kCostCounts * 4 + 1;
static_assert(kCostBytesPerPixel == kCostCountBytes);
constexpr unsigned char kCostTraced = 1, kCostTracedSpan = 2;

// Field k of a pixel (PixelCost or const PixelCost).
template <class P>
auto* cost_field(P& p, size_t k) {
  decltype(&p.rays_eye) f[kCostCounts] = {&p.rays_eye, &p.rays_reflected, &p.rays_refracted,
                                          &p.rays_shadow, &p.tests_shadow_volume};
  return f[k];
}

}  // namespace

Result<std::string> encode_band_cost(const CostBuffer& cost) {
  const size_t n = cost.pixels.size();
  if (cost.width < 1 || cost.height() < 1 || n != static_cast<size_t>(cost.width) * cost.height())
    return InvalidArgument("cannot encode the cost counts of a band of no pixels");
  std::string raw(n * kCostBytesPerPixel, '\0');
  for (size_t k = 0; k < kCostCounts; ++k) {
    char* plane = raw.data() + k * n * 4;
    for (size_t i = 0; i < n; ++i) {
      const uint32_t v = *cost_field(cost.pixels[i], k);
      for (int b = 0; b < 4; ++b) plane[i * 4 + b] = static_cast<char>((v >> (8 * b)) & 0xff);
    }
  }
  char* flags = raw.data() + kCostCounts * n * 4;
  for (size_t i = 0; i < n; ++i) {
    flags[i] = static_cast<char>((cost.pixels[i].traced ? kCostTraced : 0) |
                                 (cost.pixels[i].traced_span ? kCostTracedSpan : 0));
  }
  std::string z(ZSTD_compressBound(raw.size()), '\0');
  const size_t got = ZSTD_compress(z.data(), z.size(), raw.data(), raw.size(), kZstdLevel);
  if (ZSTD_isError(got)) return Internal(std::string("zstd: ") + ZSTD_getErrorName(got));
  z.resize(got);
  return z;
}

namespace {

// Every check decode_band_cost makes but the flags': `raw` gets the planes.
Status inflate_cost(std::string_view bytes, int64_t pixels, std::string& raw) {
  const std::string what = "the cost counts of a band of " + std::to_string(pixels) + " pixels";
  // At most kMaxDecodedBandBytes inflated, as for pixels (a job with cost
  // maps has bands small enough: min_bands).
  if (pixels < 1 || pixels > kMaxDecodedBandBytes / static_cast<int64_t>(kCostBytesPerPixel))
    return InvalidArgument(what + ": the size is out of range");
  return inflate_exactly(bytes, static_cast<size_t>(pixels) * kCostBytesPerPixel, what, raw);
}

}  // namespace

Status check_band_cost(std::string_view bytes, int64_t pixels) {
  std::string raw;
  return inflate_cost(bytes, pixels, raw);
}

Result<CostBuffer> decode_band_cost(std::string_view bytes, int width, int y0, int y1) {
  if (width < 1 || y1 <= y0) return InvalidArgument("the cost counts of a band of no pixels");
  std::string raw;
  if (Status s = inflate_cost(bytes, static_cast<int64_t>(width) * (y1 - y0), raw); !s.ok())
    return s;
  CostBuffer cost;
  cost.reset(width, y0, y1);
  const size_t n = cost.pixels.size();
  const auto* u = reinterpret_cast<const unsigned char*>(raw.data());
  for (size_t k = 0; k < kCostCounts; ++k) {
    const unsigned char* plane = u + k * n * 4;
    for (size_t i = 0; i < n; ++i) {
      const unsigned char* b = plane + i * 4;
      *cost_field(cost.pixels[i], k) =
          uint32_t{b[0]} | uint32_t{b[1]} << 8 | uint32_t{b[2]} << 16 | uint32_t{b[3]} << 24;
    }
  }
  const unsigned char* flags = u + kCostCounts * n * 4;
  for (size_t i = 0; i < n; ++i) {
    if (flags[i] & ~(kCostTraced | kCostTracedSpan)) {
      return InvalidArgument("the cost counts of a band: pixel " + std::to_string(i) +
                             " has unknown flags " + std::to_string(flags[i]));
    }
    cost.pixels[i].traced = flags[i] & kCostTraced;
    cost.pixels[i].traced_span = flags[i] & kCostTracedSpan;
  }
  return cost;
}

}  // namespace locus::farm
