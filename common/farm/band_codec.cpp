#include "common/farm/band_codec.h"

#include <zstd.h>

#include <bit>
#include <cstring>
#include <optional>

#include "common/base/image.h"

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

}  // namespace

BandEncoding band_encoding_for(const std::string& output) {
  switch (output_sample_format(output)) {
    case SampleFormat::kUint8:
      return BandEncoding::kRgb8Zstd;
    case SampleFormat::kUint16:
      return BandEncoding::kRgb16Zstd;
    case SampleFormat::kFloat32:
      return BandEncoding::kFloat32Zstd;
    case SampleFormat::kUnsupported:
      break;
  }
  return BandEncoding::kFloat32;
}

Result<EncodedBand> encode_band(BandEncoding encoding, int width, int rows,
                                const std::vector<float>& rgb) {
  const std::optional<Layout> l = layout_of(encoding);
  if (!l) return InvalidArgument("cannot encode a band in " + encoding_name(encoding));
  if (width < 1 || rows < 1 || rgb.size() != static_cast<size_t>(width) * rows * 3) {
    std::string m = "cannot encode a band of ";
    m.append(band_size_text(width, rows)).append(" pixels from ");
    m.append(std::to_string(rgb.size())).append(" floats");
    return InvalidArgument(m);
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

Result<std::vector<float>> decode_band(const EncodedBand& band) {
  const std::optional<Layout> l = layout_of(band.encoding);
  if (!l) return InvalidArgument("band pixels in " + encoding_name(band.encoding));
  const std::string what = encoding_name(band.encoding) + " band of " +
                           band_size_text(band.width, band.rows) + " pixels";
  if (band.width < 1 || band.rows < 1 ||
      static_cast<int64_t>(band.width) * band.rows > kMaxDecodedBandBytes / 12) {
    std::string m = what;
    m.append(": the size is out of range (at most ");
    m.append(std::to_string(kMaxDecodedBandBytes / 12)).append(" pixels)");
    return InvalidArgument(m);
  }
  const size_t n = static_cast<size_t>(band.width) * band.rows * 3;
  const size_t expected = n * l->sample_bytes;
  const std::string* raw = &band.bytes;
  std::string inflated;
  if (l->zstd) {
    // The frame must say its size, and that size must be the band's: a
    // payload claiming more is refused before anything is allocated.
    const unsigned long long claimed =
        ZSTD_getFrameContentSize(band.bytes.data(), band.bytes.size());
    if (claimed == ZSTD_CONTENTSIZE_ERROR || claimed == ZSTD_CONTENTSIZE_UNKNOWN) {
      return InvalidArgument(what + ": the payload is not a zstd frame with its size");
    }
    if (claimed != expected) {
      std::string m = what;
      m.append(": the zstd frame holds ").append(std::to_string(claimed));
      m.append(" bytes, expected ").append(std::to_string(expected));
      return InvalidArgument(m);
    }
    inflated.resize(expected);
    // Bounded by the destination's size, whatever the frames say.
    const size_t got =
        ZSTD_decompress(inflated.data(), inflated.size(), band.bytes.data(), band.bytes.size());
    if (ZSTD_isError(got)) {
      return InvalidArgument(what + ": corrupt or truncated zstd payload (" +
                             ZSTD_getErrorName(got) + ")");
    }
    if (got != expected) {
      std::string m = what;
      m.append(": the zstd payload holds ").append(std::to_string(got));
      m.append(" bytes, expected ").append(std::to_string(expected));
      return InvalidArgument(m);
    }
    raw = &inflated;
  } else if (band.bytes.size() != expected) {
    std::string m = what;
    m.append(": ").append(std::to_string(band.bytes.size())).append(" bytes, expected ");
    m.append(std::to_string(expected));
    return InvalidArgument(m);
  }
  const std::vector<uint32_t> samples = unpack(*raw, n, *l);
  std::string().swap(inflated);  // the largest band holds one copy less at a time
  std::vector<float> rgb(n);
  for (size_t i = 0; i < n; ++i) rgb[i] = float_of(band.encoding, samples[i]);
  return rgb;
}

}  // namespace locus::farm
