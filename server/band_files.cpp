#include "server/band_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

// A band file: this header, then n floats, then the FNV-1a hash of the
// header and the floats. Native byte order: the files never leave the
// coordinator's machine.
constexpr char kMagic[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '1'};
struct Header {
  char magic[8];
  int32_t width;
  int32_t y0;
  int32_t y1;
  int32_t reserved;
  uint64_t floats;
};

uint64_t fnv1a(const void* data, size_t n, uint64_t h = 14695981039346656037ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

std::string errno_text() { return std::strerror(errno); }

Status write_all(int fd, const void* data, size_t n, const std::string& path) {
  const char* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return Internal(path + ": cannot write: " + errno_text());
    }
    p += w;
    n -= static_cast<size_t>(w);
  }
  return Status::Ok();
}

Status fsync_path(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) return Internal(path + ": cannot open to sync: " + errno_text());
  const int r = ::fsync(fd);
  ::close(fd);
  if (r != 0) return Internal(path + ": fsync failed: " + errno_text());
  return Status::Ok();
}

}  // namespace

std::string band_file_path(const std::string& job_dir, int frame, int band) {
  return (fs::path(job_dir) / "bands" /
          (std::to_string(frame) + "-" + std::to_string(band) + ".band"))
      .string();
}

Result<std::string> write_band_temp(const std::string& job_dir, int frame, int band,
                                    const BandPixels& rows, const std::vector<float>& rgb,
                                    const std::string& tag, bool sync) {
  std::error_code ec;
  fs::create_directories(fs::path(job_dir) / "bands", ec);
  if (ec) return Internal(job_dir + "/bands: cannot create: " + ec.message());
  // The tag (a lease id from the wire) is reduced to safe characters.
  std::string safe;
  for (char c : tag.substr(0, 64)) safe += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  const std::string temp = band_file_path(job_dir, frame, band) + "." + safe + ".tmp";
  Header h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.width = rows.width;
  h.y0 = rows.y0;
  h.y1 = rows.y1;
  h.floats = rgb.size();
  uint64_t sum = fnv1a(&h, sizeof h);
  sum = fnv1a(rgb.data(), rgb.size() * sizeof(float), sum);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Internal(temp + ": cannot create: " + errno_text());
  Status st = write_all(fd, &h, sizeof h, temp);
  if (st.ok()) st = write_all(fd, rgb.data(), rgb.size() * sizeof(float), temp);
  if (st.ok()) st = write_all(fd, &sum, sizeof sum, temp);
  if (st.ok() && sync && ::fsync(fd) != 0) st = Internal(temp + ": fsync failed: " + errno_text());
  if (::close(fd) != 0 && st.ok()) st = Internal(temp + ": cannot close: " + errno_text());
  if (!st.ok()) {
    fs::remove(temp, ec);
    return st;
  }
  return temp;
}

Status commit_band_file(const std::string& temp, const std::string& path) {
  if (::rename(temp.c_str(), path.c_str()) != 0)
    return Internal(path + ": cannot rename into place: " + errno_text());
  return Status::Ok();
}

Result<std::vector<float>> read_band_file(const std::string& path, const BandPixels& rows) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return NotFound(path + ": " + errno_text());
  auto read_all = [&](void* data, size_t n) {
    char* p = static_cast<char*>(data);
    while (n > 0) {
      const ssize_t r = ::read(fd, p, n);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) return false;
      p += r;
      n -= static_cast<size_t>(r);
    }
    return true;
  };
  Header h{};
  const uint64_t expected = static_cast<uint64_t>(rows.width) * (rows.y1 - rows.y0) * 3;
  std::vector<float> rgb;
  uint64_t sum = 0;
  char extra;
  bool good = read_all(&h, sizeof h) && std::memcmp(h.magic, kMagic, sizeof kMagic) == 0 &&
              h.width == rows.width && h.y0 == rows.y0 && h.y1 == rows.y1 && h.floats == expected;
  if (good) {
    rgb.resize(expected);
    good = read_all(rgb.data(), expected * sizeof(float)) && read_all(&sum, sizeof sum) &&
           ::read(fd, &extra, 1) == 0;
  }
  ::close(fd);
  if (good) {
    good = sum == fnv1a(rgb.data(), rgb.size() * sizeof(float), fnv1a(&h, sizeof h));
  }
  if (!good) return Internal(path + ": not a complete band file for these rows");
  return rgb;
}

Result<Image> stitch_frame(const std::string& job_dir, const FrameReady& f) {
  Image image(f.width, f.height);
  for (int b = 0; b < f.bands; ++b) {
    const Band rows = band_rows(f.height, f.bands, f.band_edges, b);
    auto px = read_band_file(band_file_path(job_dir, f.frame, b), {f.width, rows.y0, rows.y1});
    if (!px.ok()) return px.status();
    std::copy(px->begin(), px->end(),
              image.rgb.begin() + static_cast<size_t>(rows.y0) * f.width * 3);
  }
  return image;
}

Status write_frame_file(const std::string& job_dir, const std::string& file_name,
                        const Image& image, bool sync) {
  const fs::path dir(job_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Internal(dir.string() + ": cannot create: " + ec.message());
  const fs::path final_path = dir / file_name;
  const fs::path temp = dir / (".partial-" + file_name);
  Status st = write_image(temp.string(), image);
  if (st.ok() && sync) st = fsync_path(temp.string(), false);
  if (st.ok() && ::rename(temp.c_str(), final_path.c_str()) != 0)
    st = Internal(final_path.string() + ": cannot rename into place: " + errno_text());
  if (!st.ok()) {
    fs::remove(temp, ec);
    return st;
  }
  // The rename itself reaches the disk before the store says "written".
  if (sync) return fsync_path(dir.string(), true);
  return Status::Ok();
}

void remove_band_files(const std::string& job_dir, int frame, int bands) {
  std::error_code ec;
  for (int b = 0; b < bands; ++b) fs::remove(band_file_path(job_dir, frame, b), ec);
}

void remove_band_temporaries(const std::string& job_dir) {
  std::error_code ec;
  const fs::path dir = fs::path(job_dir) / "bands";
  if (!fs::is_directory(dir, ec)) return;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (e.path().extension() == ".tmp") fs::remove(e.path(), ec);
  }
}

}  // namespace locus::farm
