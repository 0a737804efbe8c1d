// liblocus-image-io.so: image files through OpenImageIO, behind the table
// of common/base/image_plugin.h. Loaded by common/base/image.cpp on first
// use; nothing else links OpenImageIO.
#include <OpenImageIO/imageio.h>

#include <cstddef>
#include <vector>

#include "common/base/image_plugin.h"

namespace {

bool write16(const char* path, int width, int height, const uint16_t* samples, std::string* error) {
  auto out = OIIO::ImageOutput::create(path);
  if (!out) {
    *error = "cannot create image writer: " + OIIO::geterror();
    return false;
  }
  const OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT16);
  if (!out->open(path, spec) || !out->write_image(OIIO::TypeDesc::UINT16, samples)) {
    *error = "cannot write image: " + out->geterror();
    return false;
  }
  if (!out->close()) {
    *error = "cannot finish image: " + out->geterror();
    return false;
  }
  return true;
}

int read(const char* path, locus::Image* image, std::string* error) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    *error = "cannot read image: " + OIIO::geterror();
    return 1;
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.nchannels < 3) {
    *error = "expected an RGB image";
    return 2;
  }
  const size_t pixels = static_cast<size_t>(spec.width) * spec.height;
  std::vector<float> all(pixels * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data())) {
    *error = "cannot decode image: " + in->geterror();
    return 2;
  }
  *image = locus::Image(spec.width, spec.height);
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) image->rgb[p * 3 + c] = all[p * spec.nchannels + c];
  }
  return 0;
}

const locus::ImagePlugin kPlugin{locus::kImagePluginAbi, &write16, &read};

}  // namespace

extern "C" __attribute__((visibility("default"))) const locus::ImagePlugin* locus_image_plugin() {
  return &kPlugin;
}
