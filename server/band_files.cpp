#include "server/band_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "server/syncs.h"

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

// A band's record: this header, the payload, then the FNV-1a hash of the
// header and the payload. Native byte order: records never leave the
// coordinator's machine. "LOCBAND1" is 0.13's band file: `reserved` 0 and
// `size` the count of floats that follow; "LOCBAND2" has the encoding in
// `reserved` and the payload's bytes in `size`.
constexpr char kMagic1[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '1'};
constexpr char kMagic2[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '2'};
struct Header {
  char magic[8];
  int32_t width;
  int32_t y0;
  int32_t y1;
  int32_t reserved;
  uint64_t size;
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

Status fsync_path(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) return Internal(path + ": cannot open to sync: " + errno_text());
  const int r = counted_fsync(fd);
  ::close(fd);
  if (r != 0) return Internal(path + ": fsync failed: " + errno_text());
  return Status::Ok();
}

}  // namespace

std::string pack_band(const BandPixels& rows, const EncodedBand& band) {
  Header h{};
  std::memcpy(h.magic, kMagic2, sizeof kMagic2);
  h.width = rows.width;
  h.y0 = rows.y0;
  h.y1 = rows.y1;
  h.reserved = static_cast<int32_t>(band.encoding);
  h.size = band.bytes.size();
  const uint64_t sum = fnv1a(band.bytes.data(), band.bytes.size(), fnv1a(&h, sizeof h));
  std::string record(sizeof h + band.bytes.size() + sizeof sum, '\0');
  std::memcpy(record.data(), &h, sizeof h);
  std::memcpy(record.data() + sizeof h, band.bytes.data(), band.bytes.size());
  std::memcpy(record.data() + sizeof h + band.bytes.size(), &sum, sizeof sum);
  return record;
}

Result<EncodedBand> unpack_record(std::string_view record, const BandPixels& rows) {
  const auto refuse = [] {
    return Status(Code::kInternal, "not a complete band record for these rows");
  };
  Header h{};
  if (record.size() < sizeof h + sizeof(uint64_t)) return refuse();
  std::memcpy(&h, record.data(), sizeof h);
  const bool v1 = std::memcmp(h.magic, kMagic1, sizeof kMagic1) == 0;
  const bool v2 = std::memcmp(h.magic, kMagic2, sizeof kMagic2) == 0;
  if ((!v1 && !v2) || h.width != rows.width || h.y0 != rows.y0 || h.y1 != rows.y1) return refuse();
  const uint64_t payload = record.size() - sizeof h - sizeof(uint64_t);
  if (payload != (v1 ? h.size * sizeof(float) : h.size)) return refuse();
  uint64_t sum = 0;
  std::memcpy(&sum, record.data() + sizeof h + payload, sizeof sum);
  if (sum != fnv1a(record.data() + sizeof h, payload, fnv1a(&h, sizeof h))) return refuse();
  EncodedBand band;
  band.encoding = v1 ? BandEncoding::kFloat32 : static_cast<BandEncoding>(h.reserved);
  band.width = rows.width;
  band.rows = rows.y1 - rows.y0;
  band.bytes.assign(record.data() + sizeof h, payload);
  return band;
}

Result<std::vector<float>> unpack_band(std::string_view record, const BandPixels& rows) {
  auto band = unpack_record(record, rows);
  if (!band.ok()) return band.status();
  auto rgb = decode_band(*band);
  if (!rgb.ok()) return Status(Code::kInternal, rgb.status().message());
  return rgb;
}

EncodedBand stored_band(const BandOutput& output, const BandPixels& rows) {
  if (!output.encoded.bytes.empty()) return output.encoded;
  EncodedBand band;
  band.encoding = BandEncoding::kFloat32;
  band.width = rows.width;
  band.rows = rows.y1 - rows.y0;
  band.bytes.assign(reinterpret_cast<const char*>(output.rgb.data()),
                    output.rgb.size() * sizeof(float));
  return band;
}

std::string band_file_path(const std::string& job_dir, int frame, int band) {
  return (fs::path(job_dir) / "bands" /
          (std::to_string(frame) + "-" + std::to_string(band) + ".band"))
      .string();
}

Result<std::string> read_band_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(path + ": " + errno_text());
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

Result<Image> stitch_frame(const FrameReady& f,
                           const std::function<Result<std::string>(int band)>& record) {
  Image image(f.width, f.height);
  for (int b = 0; b < f.bands; ++b) {
    const Band rows = band_rows(f.height, f.bands, f.band_edges, b);
    auto bytes = record(b);
    if (!bytes.ok()) return bytes.status();
    auto px = unpack_band(*bytes, {f.width, rows.y0, rows.y1});
    if (!px.ok()) {
      return Status(px.status().code(), "band " + std::to_string(b) + " of frame " +
                                            std::to_string(f.frame) + ": " + px.status().message());
    }
    std::copy(px->begin(), px->end(),
              image.rgb.begin() + static_cast<size_t>(rows.y0) * f.width * 3);
  }
  return image;
}

namespace {

// Writes job_dir/file_name through a temporary name, `write` making the
// temporary file; fsyncs the file when `sync`, and then the directory when
// `sync_dir` too.
Status write_atomically(const std::string& job_dir, const std::string& file_name,
                        const std::function<Status(const std::string& path)>& write, bool sync,
                        bool sync_dir = true) {
  const fs::path dir(job_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Internal(dir.string() + ": cannot create: " + ec.message());
  const fs::path final_path = dir / file_name;
  const fs::path temp = dir / (".partial-" + file_name);
  Status st = write(temp.string());
  if (st.ok() && sync) st = fsync_path(temp.string(), false);
  if (st.ok() && ::rename(temp.c_str(), final_path.c_str()) != 0)
    st = Internal(final_path.string() + ": cannot rename into place: " + errno_text());
  if (!st.ok()) {
    fs::remove(temp, ec);
    return st;
  }
  // The rename itself reaches the disk before the store says "written".
  if (sync && sync_dir) return fsync_path(dir.string(), true);
  return Status::Ok();
}

}  // namespace

Status write_frame_file(const std::string& job_dir, const std::string& file_name,
                        const Image& image, bool sync, bool sync_dir) {
  return write_atomically(
      job_dir, file_name, [&](const std::string& path) { return write_image(path, image); }, sync,
      sync_dir);
}

Status sync_directory(const std::string& dir) { return fsync_path(dir, true); }

Status write_frame(const std::string& job_dir, const FrameReady& f,
                   const std::function<Result<std::string>(int band)>& record, bool sync,
                   bool sync_dir) {
  // A PNG whose bands all came as png8+deflate: joined as they are
  // (png_from_bands), nothing decoded or compressed here.
  std::vector<EncodedBand> deflated;
  std::vector<std::string> records;  // read for the join, so not read twice
  if (output_sample_format(f.file_name) == SampleFormat::kUint8) {
    for (int b = 0; b < f.bands; ++b) {
      const Band rows = band_rows(f.height, f.bands, f.band_edges, b);
      auto bytes = record(b);
      if (!bytes.ok()) return bytes.status();
      records.push_back(std::move(*bytes));
      auto band = unpack_record(records.back(), {f.width, rows.y0, rows.y1});
      if (!band.ok() || band->encoding != BandEncoding::kPng8Deflate) break;
      deflated.push_back(std::move(*band));
    }
  }
  if (static_cast<int>(deflated.size()) == f.bands) {
    auto png = png_from_bands(f.width, f.height, deflated);
    if (!png.ok()) return png.status();
    deflated.clear();
    return write_atomically(
        job_dir, f.file_name, [&](const std::string& path) { return write_file(path, *png); },
        sync, sync_dir);
  }
  // Otherwise (other outputs, older workers' bands, a damaged record named
  // by stitch_frame): the frame's pixels, encoded by write_image.
  deflated.clear();
  auto image = stitch_frame(f, [&](int b) -> Result<std::string> {
    if (b < static_cast<int>(records.size())) return std::move(records[b]);
    return record(b);
  });
  if (!image.ok()) return image.status();
  return write_frame_file(job_dir, f.file_name, *image, sync, sync_dir);
}

}  // namespace locus::farm
