#include "common/base/exr.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfThreading.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <fstream>
#include <mutex>
#include <thread>

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

// OpenEXR compresses (ZIP, about 100 ms for a 512x512 frame on one core)
// and decompresses blocks of lines on its own thread pool: one per core,
// at most 8, made once.
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
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    for (const char* c : kChannels) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::OutputFile file(path.c_str(), header, exr_threads());
    Image& pixels = const_cast<Image&>(image);  // OpenEXR's slices take char*; only read
    file.setFrameBuffer(frame_buffer(pixels, 0, 0));
    file.writePixels(image.height);
  } catch (const std::exception& e) {
    return Internal(path + ": cannot write the EXR: " + e.what());
  }
  return Status::Ok();
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

bool is_exr_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[4] = {0, 0, 0, 0};
  in.read(reinterpret_cast<char*>(magic), 4);
  return in && magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01;
}

}  // namespace locus
