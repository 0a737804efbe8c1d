#include "common/base/image.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>

namespace locus {

Status write_image(const std::string& path, const Image& image, bool for_display) {
  const SampleFormat format = output_sample_format(path);
  if (format == SampleFormat::kUnsupported) {
    return InvalidArgument(path + ": unsupported image type '" + lower_extension(path) +
                           "' (expected .png, .exr, .tif)");
  }
  if (image.width <= 0 || image.height <= 0) return InvalidArgument(path + ": empty image");
  auto out = OIIO::ImageOutput::create(path);
  if (!out) return Internal(path + ": cannot create image writer: " + OIIO::geterror());
  bool ok = false;
  if (format == SampleFormat::kFloat32) {
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::FLOAT);
    spec.attribute("compression", "zip");
    ok = out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, image.rgb.data());
  } else if (format == SampleFormat::kUint8) {
    // SHADING.md "Output": round(255 * clamp(v, 0, 1)), no transfer curve.
    std::vector<uint8_t> px(image.rgb.size());
    for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint8_t>(quantize8(image.rgb[i]));
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", for_display ? "sRGB" : "Linear");
    spec.attribute("png:compressionLevel", kPngLevel);
    ok = out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data());
  } else {
    std::vector<uint16_t> px(image.rgb.size());
    for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint16_t>(quantize16(image.rgb[i]));
    OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT16);
    ok = out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT16, px.data());
  }
  if (!ok) return Internal(path + ": cannot write image: " + out->geterror());
  if (!out->close()) return Internal(path + ": cannot finish image: " + out->geterror());
  return Status::Ok();
}

Result<Image> read_image(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return NotFound(path + ": cannot read image: " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels < 3) return InvalidArgument(path + ": expected an RGB image");
  Image img(spec.width, spec.height);
  std::vector<float> all(static_cast<size_t>(spec.width) * spec.height * spec.nchannels);
  // 8-bit files are read back as their stored code values / 255.
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data())) {
    return InvalidArgument(path + ": cannot decode image: " + in->geterror());
  }
  for (size_t p = 0; p < static_cast<size_t>(spec.width) * spec.height; ++p) {
    for (int c = 0; c < 3; ++c) img.rgb[p * 3 + c] = all[p * spec.nchannels + c];
  }
  return img;
}

}  // namespace locus
