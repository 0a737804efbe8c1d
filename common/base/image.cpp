// Image files: PNGs written here (png.h), EXRs through OpenEXR (exr.h);
// TIFF and every other read through the image plugin (image_plugin.h),
// loaded on first use.
#include "common/base/image.h"

#include <dlfcn.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/base/exr.h"
#include "common/base/image_plugin.h"
#include "common/base/png.h"

namespace locus {
namespace {

namespace fs = std::filesystem;

struct LoadedPlugin {
  const ImagePlugin* plugin = nullptr;
  std::string error;  // why there is none
};

// Loaded once per process (a function-local static: thread-safe), never
// unloaded.
const LoadedPlugin& loaded_plugin() {
  static const LoadedPlugin loaded = [] {
    LoadedPlugin l;
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) {
      l.error = "cannot find this executable's directory (/proc/self/exe: " + ec.message() + ")";
      return l;
    }
    const fs::path path =
        (exe.parent_path() / ".." / "lib" / "locus" / kImagePluginFile).lexically_normal();
    const std::string where = "the image plugin " + path.string() +
                              " (looked for in ../lib/locus/ from the executable's directory, "
                              "where the package and the build put it)";
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* why = dlerror();
      l.error = "cannot load " + where + ": " + (why ? why : "unknown error");
      return l;
    }
    using Entry = const ImagePlugin* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(handle, kImagePluginEntry));
    const ImagePlugin* plugin = entry ? entry() : nullptr;
    if (!plugin || plugin->abi != kImagePluginAbi || !plugin->write16 || !plugin->read) {
      l.error = where + " is of another build (its interface is " +
                (plugin ? std::to_string(plugin->abi) : std::string("missing")) +
                ", this build's " + std::to_string(kImagePluginAbi) + ")";
      return l;
    }
    l.plugin = plugin;
    return l;
  }();
  return loaded;
}

}  // namespace

Status write_file(const std::string& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) return Internal(path + ": cannot write: " + std::strerror(errno));
  return Status::Ok();
}

Status write_image(const std::string& path, const Image& image, bool for_display) {
  const SampleFormat format = output_sample_format(path);
  if (format == SampleFormat::kUnsupported) {
    return InvalidArgument(path + ": unsupported image type '" + lower_extension(path) +
                           "' (expected .png, .exr, .tif)");
  }
  if (image.width <= 0 || image.height <= 0) return InvalidArgument(path + ": empty image");
  if (format == SampleFormat::kUint8) {
    // SHADING.md "Output": round(255 * clamp(v, 0, 1)), no transfer curve.
    auto png = encode_png(image, for_display ? PngTag::kDisplay : PngTag::kLinear);
    if (!png.ok()) return Internal(path + ": " + png.status().message());
    return write_file(path, *png);
  }
  if (format == SampleFormat::kFloat32) return write_exr(path, image);
  const LoadedPlugin& l = loaded_plugin();
  if (!l.plugin) return Internal(path + ": cannot write it: " + l.error);
  std::vector<uint16_t> px(image.rgb.size());
  for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<uint16_t>(quantize16(image.rgb[i]));
  std::string error;
  if (!l.plugin->write16(path.c_str(), image.width, image.height, px.data(), &error)) {
    return Internal(path + ": " + error);
  }
  return Status::Ok();
}

Result<Image> read_image(const std::string& path) {
  if (is_exr_file(path)) return read_exr(path);
  const LoadedPlugin& l = loaded_plugin();
  if (!l.plugin) return Internal(path + ": cannot read it: " + l.error);
  Image image;
  std::string error;
  const int r = l.plugin->read(path.c_str(), &image, &error);
  if (r == 1) return NotFound(path + ": " + error);
  if (r != 0) return InvalidArgument(path + ": " + error);
  return image;
}

}  // namespace locus
