#include "server/band_files.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/base/cost_map.h"
#include "common/base/exr.h"
#include "server/syncs.h"

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

// A band's record: this header, the payload, then the FNV-1a hash of the
// header and the payload. Native byte order: records never leave the
// coordinator's machine. "LOCBAND1" is 0.13's band file: `reserved` 0 and
// `size` the count of floats that follow; "LOCBAND2" has the encoding in
// `reserved` and the payload's bytes in `size`; "LOCBAND3" is LOCBAND2
// whose payload goes on after those bytes with the band's cost counts
// (encode_band_cost's bytes, a job with cost maps).
constexpr char kMagic1[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '1'};
constexpr char kMagic2[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '2'};
constexpr char kMagic3[8] = {'L', 'O', 'C', 'B', 'A', 'N', 'D', '3'};
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

std::string pack_band(const BandPixels& rows, const EncodedBand& band, std::string_view cost) {
  Header h{};
  std::memcpy(h.magic, cost.empty() ? kMagic2 : kMagic3, sizeof kMagic2);
  h.width = rows.width;
  h.y0 = rows.y0;
  h.y1 = rows.y1;
  h.reserved = static_cast<int32_t>(band.encoding);
  h.size = band.bytes.size();
  const size_t payload = band.bytes.size() + cost.size();
  std::string record(sizeof h + payload + sizeof(uint64_t), '\0');
  char* p = record.data();
  std::memcpy(p, &h, sizeof h);
  std::memcpy(p + sizeof h, band.bytes.data(), band.bytes.size());
  if (!cost.empty()) std::memcpy(p + sizeof h + band.bytes.size(), cost.data(), cost.size());
  const uint64_t sum = fnv1a(p + sizeof h, payload, fnv1a(&h, sizeof h));
  std::memcpy(p + sizeof h + payload, &sum, sizeof sum);
  return record;
}

namespace {

// A checked record's parts: its encoding, its pixel bytes and its cost
// bytes (empty: none).
struct RecordParts {
  BandEncoding encoding = BandEncoding::kFloat32;
  std::string_view pixels;
  std::string_view cost;
};

Result<RecordParts> record_parts(std::string_view record, const BandPixels& rows) {
  const auto refuse = [] {
    return Status(Code::kInternal, "not a complete band record for these rows");
  };
  Header h{};
  if (record.size() < sizeof h + sizeof(uint64_t)) return refuse();
  std::memcpy(&h, record.data(), sizeof h);
  const bool v1 = std::memcmp(h.magic, kMagic1, sizeof kMagic1) == 0;
  const bool v2 = std::memcmp(h.magic, kMagic2, sizeof kMagic2) == 0;
  const bool v3 = std::memcmp(h.magic, kMagic3, sizeof kMagic3) == 0;
  if ((!v1 && !v2 && !v3) || h.width != rows.width || h.y0 != rows.y0 || h.y1 != rows.y1)
    return refuse();
  const uint64_t payload = record.size() - sizeof h - sizeof(uint64_t);
  const uint64_t pixels = v1 ? h.size * sizeof(float) : h.size;
  if (v3 ? pixels >= payload : pixels != payload) return refuse();
  uint64_t sum = 0;
  std::memcpy(&sum, record.data() + sizeof h + payload, sizeof sum);
  if (sum != fnv1a(record.data() + sizeof h, payload, fnv1a(&h, sizeof h))) return refuse();
  RecordParts parts;
  parts.encoding = v1 ? BandEncoding::kFloat32 : static_cast<BandEncoding>(h.reserved);
  parts.pixels = record.substr(sizeof h, pixels);
  parts.cost = record.substr(sizeof h + pixels, payload - pixels);
  return parts;
}

}  // namespace

Result<EncodedBand> unpack_record(std::string_view record, const BandPixels& rows) {
  auto parts = record_parts(record, rows);
  if (!parts.ok()) return parts.status();
  EncodedBand band;
  band.encoding = parts->encoding;
  band.width = rows.width;
  band.rows = rows.y1 - rows.y0;
  band.bytes.assign(parts->pixels);
  return band;
}

Result<std::string> unpack_cost(std::string_view record, const BandPixels& rows) {
  auto parts = record_parts(record, rows);
  if (!parts.ok()) return parts.status();
  return std::string(parts->cost);
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

Result<CostBuffer> stitch_cost(const FrameReady& f,
                               const std::function<Result<std::string_view>(int band)>& record,
                               int* bands_in) {
  CostBuffer cost;
  cost.reset(f.width, 0, f.height);
  if (bands_in) *bands_in = 0;
  for (int b = 0; b < f.bands; ++b) {
    const Band rows = band_rows(f.height, f.bands, f.band_edges, b);
    const std::string where = "band " + std::to_string(b) + " of frame " + std::to_string(f.frame);
    auto bytes = record(b);
    if (bands_in && !bytes.ok() && bytes.status().code() == Code::kNotFound) continue;
    if (!bytes.ok()) return bytes.status();
    if (bands_in) ++*bands_in;
    auto counts = unpack_cost(*bytes, {f.width, rows.y0, rows.y1});
    if (!counts.ok())
      return Status(counts.status().code(), where + ": " + counts.status().message());
    if (counts->empty()) {
      // A worker of an older release ignores BandTask.cost_map. Said once,
      // when the frame's map is written, not at every look at a frame in
      // progress.
      if (!bands_in)
        spdlog::warn("job {}: {} came without cost counts; its rows of {} are empty", f.job_id,
                     where, f.cost_file_name);
      continue;
    }
    auto band = decode_band_cost(*counts, f.width, rows.y0, rows.y1);
    if (!band.ok()) return Status(Code::kInternal, where + ": " + band.status().message());
    std::copy(band->pixels.begin(), band->pixels.end(),
              cost.pixels.begin() + static_cast<size_t>(rows.y0) * f.width);
  }
  return cost;
}

Status write_frame(const std::string& job_dir, const FrameReady& f,
                   const std::function<Result<std::string>(int band)>& record, bool sync,
                   bool sync_dir, FrameWrite* how) {
  if (how) *how = FrameWrite::kJoined;
  // Each band's record is read once, in band order, and kept for the
  // frame's steps below.
  std::vector<std::string> records;
  records.reserve(f.bands);
  const auto read = [&](int b) -> Result<const std::string*> {
    if (b < static_cast<int>(records.size())) return &records[b];
    auto bytes = record(b);
    if (!bytes.ok()) return bytes.status();
    records.push_back(std::move(*bytes));
    return &records.back();
  };
  // The cost map first (docs/cost-map.md "On the farm"): the frame's
  // "written" vouches for both files.
  if (!f.cost_file_name.empty()) {
    auto cost = stitch_cost(f, [&](int b) -> Result<std::string_view> {
      auto bytes = read(b);
      if (!bytes.ok()) return bytes.status();
      return std::string_view(**bytes);
    });
    if (!cost.ok()) return cost.status();
    const Image map = cost_map_image(*cost);
    *cost = CostBuffer{};
    Status st = write_atomically(
        job_dir, f.cost_file_name,
        [&](const std::string& path) { return write_image(path, map, /*for_display=*/true); }, sync,
        /*sync_dir=*/false);
    if (!st.ok()) return st;
  }
  // The frame's bands when every one came in `encoding` (their first rows
  // in `y0s`); fewer when one did not (or its record does not unpack:
  // stitch_frame names it below).
  std::vector<int> y0s;
  const auto all_in = [&](BandEncoding encoding) -> Result<std::vector<EncodedBand>> {
    std::vector<EncodedBand> bands;
    y0s.clear();
    for (int b = 0; b < f.bands; ++b) {
      const Band rows = band_rows(f.height, f.bands, f.band_edges, b);
      auto bytes = read(b);
      if (!bytes.ok()) return bytes.status();
      auto band = unpack_record(**bytes, {f.width, rows.y0, rows.y1});
      if (!band.ok() || band->encoding != encoding) break;
      bands.push_back(std::move(*band));
      y0s.push_back(rows.y0);
    }
    return bands;
  };
  // A PNG whose bands all came as png8+deflate: joined as they are
  // (png_from_bands), nothing decoded or compressed here.
  std::vector<EncodedBand> deflated;
  if (output_sample_format(f.file_name) == SampleFormat::kUint8) {
    auto bands = all_in(BandEncoding::kPng8Deflate);
    if (!bands.ok()) return bands.status();
    deflated = std::move(*bands);
  }
  if (static_cast<int>(deflated.size()) == f.bands) {
    records.clear();
    auto png = png_from_bands(f.width, f.height, deflated);
    if (!png.ok()) return png.status();
    deflated.clear();
    return write_atomically(
        job_dir, f.file_name, [&](const std::string& path) { return write_file(path, *png); },
        sync, sync_dir);
  }
  deflated.clear();
  // An EXR whose bands all came as exr+zip: the blocks they hold whole as
  // they came, those across two bands compressed from their edge rows
  // (exr_blocks_from_bands), written as they are.
  if (output_sample_format(f.file_name) == SampleFormat::kFloat32) {
    auto bands = all_in(BandEncoding::kExrZip);
    if (!bands.ok()) return bands.status();
    std::vector<EncodedBand> zipped = std::move(*bands);
    if (static_cast<int>(zipped.size()) == f.bands) {
      // The blocks view the bands' bytes: `zipped` is kept until the file
      // is written.
      auto blocks = exr_blocks_from_bands(f.width, f.height, y0s, zipped);
      // Bands that do not fit together (a damaged record) are stitched
      // below, where stitch_frame names the one at fault.
      if (blocks.ok()) {
        records.clear();
        return write_atomically(
            job_dir, f.file_name,
            [&](const std::string& path) {
              return write_exr_blocks(path, f.width, f.height, blocks->blocks);
            },
            sync, sync_dir);
      }
      zipped.clear();
      spdlog::warn("job {}: frame {}'s EXR blocks: {}; stitching its pixels instead", f.job_id,
                   f.frame, blocks.status().message());
    }
  }
  // Otherwise (other outputs, older workers' bands, a damaged record named
  // by stitch_frame): the frame's pixels, encoded by write_image.
  if (how) *how = FrameWrite::kEncoded;
  auto image = stitch_frame(f, [&](int b) -> Result<std::string> {
    if (b < static_cast<int>(records.size())) return std::move(records[b]);
    return record(b);
  });
  records.clear();
  if (!image.ok()) return image.status();
  return write_frame_file(job_dir, f.file_name, *image, sync, sync_dir);
}

}  // namespace locus::farm
