#include "common/base/exr.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <fstream>
#include <mutex>
#include <thread>

#include "common/base/deflate.h"
#include "common/base/parallel.h"

namespace locus {
namespace {

constexpr const char* kChannels[3] = {"R", "G", "B"};
// 2^28 pixels (3 GiB of floats): beyond any frame Locus renders.
constexpr int64_t kMaxPixels = int64_t{1} << 28;

// The frame buffer of `image` for OpenEXR, whose data window starts at
// (x0, y0): a slice a channel, interleaved.
Imf::FrameBuffer frame_buffer(Image& image, int x0, int y0) {
  const size_t xs = sizeof(float) * 3, ys = xs * static_cast<size_t>(image.width);
  // OpenEXR addresses pixel (x, y) at base + x * xs + y * ys.
  char* base = reinterpret_cast<char*>(image.rgb.data()) - static_cast<ptrdiff_t>(x0) * xs -
               static_cast<ptrdiff_t>(y0) * ys;
  Imf::FrameBuffer fb;
  for (int c = 0; c < 3; ++c) {
    fb.insert(kChannels[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), xs, ys, 1, 1, 0.0));
  }
  return fb;
}

// OpenEXR decompresses blocks of lines on its own thread pool, and
// write_exr compresses them on as many threads: one per core, at most 8
// (the pool made once).
int exr_threads() {
  static std::once_flag once;
  static int threads = 0;
  std::call_once(once, [] {
    threads = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
    Imf::setGlobalThreadCount(threads);
  });
  return threads;
}

}  // namespace

Status write_exr(const std::string& path, const Image& image) {
  if (image.width <= 0 || image.height <= 0) return InvalidArgument(path + ": empty image");
  // Its blocks, compressed side by side, then written as they are: the
  // very bytes a farm's frame joined from its bands' blocks holds
  // (docs/farm.md "Frames").
  const int blocks = (image.height + kExrZipBlockRows - 1) / kExrZipBlockRows;
  std::vector<std::string> zipped(static_cast<size_t>(blocks));
  parallel_for(blocks, exr_threads(), [&](int k) {
    const int y = k * kExrZipBlockRows;
    zipped[static_cast<size_t>(k)] =
        exr_zip_block(image.pixel(0, y), image.width, std::min(kExrZipBlockRows, image.height - y));
  });
  return write_exr_blocks(path, image.width, image.height,
                          std::vector<std::string_view>(zipped.begin(), zipped.end()));
}

Result<Image> read_exr(const std::string& path) {
  try {
    Imf::InputFile file(path.c_str(), exr_threads());
    const Imath::Box2i window = file.header().dataWindow();
    const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
    if (w < 1 || h < 1) return InvalidArgument(path + ": the EXR holds no pixels");
    if (static_cast<int64_t>(w) * h > kMaxPixels) {
      return InvalidArgument(path + ": the EXR is " + std::to_string(w) + " x " +
                             std::to_string(h) + " pixels, more than Locus reads");
    }
    for (const char* c : kChannels) {
      if (!file.header().channels().findChannel(c)) {
        return InvalidArgument(path + ": the EXR has no channel " + c + " (expected RGB)");
      }
    }
    Image image(w, h);
    file.setFrameBuffer(frame_buffer(image, window.min.x, window.min.y));
    file.readPixels(window.min.y, window.max.y);
    return image;
  } catch (const std::exception& e) {
    std::ifstream exists(path);
    if (!exists) return NotFound(path + ": cannot read image: no such file");
    return InvalidArgument(path + ": cannot decode the EXR: " + e.what());
  }
}

// ---- Blocks compressed elsewhere

namespace {

// EXR stores a scanline's channels in the order of their names: B, G, R.
constexpr int kStoredChannel[3] = {2, 1, 0};

size_t block_bytes(int width, int rows) { return static_cast<size_t>(width) * rows * 12; }

std::string exr_error(exr_result_t r) { return exr_get_error_code_as_string(r); }

// ZIP_COMPRESSION's level: OpenEXR's default for its writer (4).
int zip_level() {
  static const int level = Imf::Header().zipCompressionLevel();
  return level;
}

// Each sample of a block in the order EXR lays it out (line by line, each
// channel's samples: B, G, R), as its float's bits: visit(k, bits) for the
// k-th. A sample's 4 bytes are stored least significant first.
template <typename F>
void for_each_stored_sample(const float* rgb, int width, int rows, F&& visit) {
  size_t k = 0;
  for (int y = 0; y < rows; ++y) {
    const float* line = rgb + static_cast<size_t>(y) * width * 3;
    for (const int c : kStoredChannel) {
      for (int x = 0; x < width; ++x, ++k) {
        uint32_t bits;
        std::memcpy(&bits, line + x * 3 + c, 4);
        visit(k, bits);
      }
    }
  }
}

}  // namespace

std::string exr_zip_block(const float* rgb, int width, int rows) {
  // ZIP_COMPRESSION's preparation of the block as EXR lays it out: its
  // even bytes, then its odd ones (a sample's bytes 0 and 2, then 1 and 3,
  // made here in one pass); each byte then replaced by its difference from
  // the one before, plus 128.
  const size_t n = block_bytes(width, rows);
  std::string split(n, '\0');
  auto* even = reinterpret_cast<unsigned char*>(split.data());
  unsigned char* odd = even + n / 2;  // n: 12 bytes a pixel
  for_each_stored_sample(rgb, width, rows, [&](size_t k, uint32_t bits) {
    even[2 * k] = static_cast<unsigned char>(bits);
    even[2 * k + 1] = static_cast<unsigned char>(bits >> 16);
    odd[2 * k] = static_cast<unsigned char>(bits >> 8);
    odd[2 * k + 1] = static_cast<unsigned char>(bits >> 24);
  });
  for (size_t i = n; i-- > 1;) even[i] = static_cast<unsigned char>(even[i] - even[i - 1] + 128);
  // By libdeflate (common/base/deflate.h). A compressor that cannot be
  // made (no memory), or a block that does not shrink, leaves the block as
  // laid out, which is as valid.
  std::string z = zlib_compress(split, zip_level());
  if (!z.empty() && z.size() < n) return z;
  std::string raw(n, '\0');
  for_each_stored_sample(rgb, width, rows, [&](size_t k, uint32_t bits) {
    for (int b = 0; b < 4; ++b) raw[4 * k + b] = static_cast<char>(bits >> (8 * b));
  });
  return raw;
}

Status exr_unzip_block(std::string_view data, int width, int rows, float* rgb,
                       const std::string& what) {
  const size_t n = block_bytes(width, rows);
  std::string raw;
  if (data.size() == n) {
    if (!rgb) return Status::Ok();
    raw.assign(data);
  } else {
    std::string split(n, '\0');
    // Bounded by the block's size, whatever the stream says; every byte of
    // the data must be the stream's.
    const Inflated r = zlib_inflate(data, split.data(), n);
    if (r.outcome == Inflated::kNoMemory)
      return Internal(what + ": no memory to decompress a ZIP block");
    if (r.outcome != Inflated::kOk) {
      std::string m = what;
      m.append(": not a ZIP block of ").append(std::to_string(rows)).append(" rows of ");
      m.append(std::to_string(width)).append(" pixels (");
      switch (r.outcome) {
        case Inflated::kTooLong:
          m.append("more bytes than the rows hold");
          break;
        case Inflated::kShort:
          m.append(std::to_string(r.made) + " bytes, expected " + std::to_string(n));
          break;
        case Inflated::kTrailing:
          m.append(std::to_string(r.trailing) + " bytes after the zlib stream");
          break;
        default:
          m.append("corrupt zlib stream");
          break;
      }
      return InvalidArgument(m.append(")"));
    }
    if (!rgb) return Status::Ok();
    auto* t = reinterpret_cast<unsigned char*>(split.data());
    for (size_t i = 1; i < n; ++i) t[i] = static_cast<unsigned char>(t[i - 1] + t[i] - 128);
    raw.assign(n, '\0');
    const size_t half = (n + 1) / 2;
    for (size_t i = 0; i < n; ++i) raw[i] = split[(i % 2 == 0 ? 0 : half) + i / 2];
  }
  const char* in = raw.data();
  for (int y = 0; y < rows; ++y) {
    float* line = rgb + static_cast<size_t>(y) * width * 3;
    for (const int c : kStoredChannel) {
      for (int x = 0; x < width; ++x, in += 4) std::memcpy(line + x * 3 + c, in, 4);
    }
  }
  return Status::Ok();
}

Status write_exr_blocks(const std::string& path, int width, int height,
                        const std::vector<std::string_view>& blocks) {
  if (width <= 0 || height <= 0) return InvalidArgument(path + ": empty image");
  const size_t expected = (static_cast<size_t>(height) + kExrZipBlockRows - 1) / kExrZipBlockRows;
  if (blocks.size() != expected) {
    return InvalidArgument(path + ": " + std::to_string(blocks.size()) + " blocks for " +
                           std::to_string(height) + " rows, expected " + std::to_string(expected));
  }
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  exr_context_t ctx = nullptr;
  // Written directly: the caller writes to a temporary name and renames.
  exr_result_t r = exr_start_write(&ctx, path.c_str(), EXR_WRITE_FILE_DIRECTLY, &init);
  if (r != EXR_ERR_SUCCESS) return Internal(path + ": cannot write the EXR: " + exr_error(r));
  int part = 0;
  r = exr_add_part(ctx, nullptr, EXR_STORAGE_SCANLINE, &part);
  if (r == EXR_ERR_SUCCESS)
    r = exr_initialize_required_attr_simple(ctx, part, width, height, EXR_COMPRESSION_ZIP);
  // As write_exr's header has them: float, not perceptually linear.
  for (const char* c : {"B", "G", "R"}) {
    if (r == EXR_ERR_SUCCESS)
      r = exr_add_channel(ctx, part, c, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
  }
  if (r == EXR_ERR_SUCCESS) r = exr_write_header(ctx);
  for (size_t k = 0; k < blocks.size() && r == EXR_ERR_SUCCESS; ++k) {
    r = exr_write_scanline_chunk(ctx, part, static_cast<int>(k) * kExrZipBlockRows,
                                 blocks[k].data(), blocks[k].size());
  }
  const exr_result_t finished = exr_finish(&ctx);
  if (r == EXR_ERR_SUCCESS) r = finished;
  if (r != EXR_ERR_SUCCESS) return Internal(path + ": cannot write the EXR: " + exr_error(r));
  return Status::Ok();
}

bool is_exr_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[4] = {0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(magic), 4);
  return in && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

}  // namespace locus
