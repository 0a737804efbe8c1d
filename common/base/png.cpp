#include "common/base/png.h"

#include <zlib.h>

#include "common/base/deflate.h"

namespace locus {
namespace {

void put_chunk(std::string& png, const char* type, std::string_view data) {
  put_be32(png, static_cast<uint32_t>(data.size()));
  png.append(type, 4);
  png.append(data);
  uLong crc = crc32(0, reinterpret_cast<const Bytef*>(type), 4);
  crc = crc32(crc, reinterpret_cast<const Bytef*>(data.data()), static_cast<uInt>(data.size()));
  put_be32(png, static_cast<uint32_t>(crc));
}

}  // namespace

void put_be32(std::string& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xff));
}

uint32_t get_be32(const char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

std::string png_filter_rows(int width, int rows, const std::vector<float>& rgb) {
  const size_t stride = static_cast<size_t>(width) * 3;
  std::string out(png_row_bytes(width) * rows, '\0');
  std::vector<unsigned char> prev(stride), cur(stride);
  for (int y = 0; y < rows; ++y) {
    for (size_t i = 0; i < stride; ++i)
      cur[i] = static_cast<unsigned char>(quantize8(rgb[y * stride + i]));
    char* o = out.data() + y * png_row_bytes(width);
    o[0] = static_cast<char>(y == 0 ? kPngFilterSub : kPngFilterUp);
    for (size_t i = 0; i < stride; ++i) {
      const unsigned char ref = y == 0 ? (i >= 3 ? cur[i - 3] : 0) : prev[i];
      o[1 + i] = static_cast<char>(static_cast<unsigned char>(cur[i] - ref));
    }
    prev.swap(cur);
  }
  return out;
}

std::string png_file(int width, int height, PngTag tag, const std::vector<std::string_view>& idat) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string header;
  put_be32(header, static_cast<uint32_t>(width));
  put_be32(header, static_cast<uint32_t>(height));
  header.append("\x08\x02\x00\x00\x00", 5);  // 8 bits, RGB, deflate, filters, no interlace
  put_chunk(png, "IHDR", header);
  if (tag == PngTag::kDisplay) {
    put_chunk(png, "sRGB", std::string_view("\0", 1));  // perceptual intent
    std::string gamma;
    put_be32(gamma, 45455);  // the gAMA the specification pairs with sRGB (11.3.3.5)
    put_chunk(png, "gAMA", gamma);
    put_chunk(png, "tEXt", std::string_view("oiio:ColorSpace\0sRGB", 20));
  } else {
    std::string gamma;
    put_be32(gamma, 100000);  // 1.0: the samples are linear
    put_chunk(png, "gAMA", gamma);
    put_chunk(png, "tEXt", std::string_view("oiio:ColorSpace\0Linear", 22));
  }
  for (std::string_view data : idat) put_chunk(png, "IDAT", data);
  put_chunk(png, "IEND", "");
  return png;
}

Result<std::string> encode_png(const Image& image, PngTag tag, int level) {
  if (image.width <= 0 || image.height <= 0) return InvalidArgument("a PNG of no pixels");
  const std::string rows = png_filter_rows(image.width, image.height, image.rgb);
  // One zlib stream of the whole image, by libdeflate (common/base/deflate.h).
  const std::string z = zlib_compress(rows, level);
  if (z.empty()) return Internal("cannot deflate the image's rows (no memory)");
  return png_file(image.width, image.height, tag, {z});
}

}  // namespace locus
