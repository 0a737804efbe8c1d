// Pixels on the coordinator's disk. Each accepted band is a record in the
// job store (its `band_pixels` table, written in the same transaction that
// marks the band done, made durable by the group commit: docs/farm.md
// "Durability"): its rows, its encoding and the bytes as the worker sent
// them (common/farm/band_codec.h), and a checksum. A frame is stitched from
// its records when its last band is in, so the coordinator holds one frame
// in memory at a time however many frames are in progress; the frame is
// written atomically (a temporary file, fsync when asked, rename) and its
// records are deleted with the store's "written". Releases up to 0.13 kept
// each band in a file of its own, DATA/jobs/<job>/bands/<frame>-<band>.band;
// a restart imports those into the store.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/cost.h"
#include "common/base/image.h"
#include "common/base/status.h"
#include "common/farm/band_codec.h"
#include "common/farm/types.h"

namespace locus::farm {

// The rows [y0, y1) of a `width`-pixel-wide frame.
struct BandPixels {
  int width = 0;
  int y0 = 0;
  int y1 = 0;
};

// A band's record for the store: a header with its rows and encoding, the
// encoded bytes, the band's cost counts when it has them (encode_band_cost's
// bytes; empty: none), the FNV-1a hash of all.
std::string pack_band(const BandPixels& rows, const EncodedBand& band, std::string_view cost = {});
// The encoded band of a record, checked against the expected rows and its
// checksum: a torn, foreign or corrupted record is an error, never pixels.
// Also reads the band files of 0.13.
Result<EncodedBand> unpack_record(std::string_view record, const BandPixels& rows);
// The cost counts' bytes of a record, checked as unpack_record checks it;
// empty: the band has none (a job without cost maps, an older worker).
Result<std::string> unpack_cost(std::string_view record, const BandPixels& rows);
// The floats of a record (unpack_record, then decode_band).
Result<std::vector<float>> unpack_band(std::string_view record, const BandPixels& rows);
// What the store keeps of a result: its bytes as they came, or (a worker of
// 0.13, or a lease that asked for floats) its floats as float32.
EncodedBand stored_band(const BandOutput& output, const BandPixels& rows);

// 0.13's band file of a band, and its bytes: a record unpack_band reads.
std::string band_file_path(const std::string& job_dir, int frame, int band);
Result<std::string> read_band_file(const std::string& path);

// One frame's image from its bands' records, `record(band)` giving each.
Result<Image> stitch_frame(const FrameReady& frame,
                           const std::function<Result<std::string>(int band)>& record);
// One frame's cost counts from its bands' records (unpack_cost,
// decode_band_cost); a band without counts (an older worker) leaves its
// rows zero, with a warning in the log. With `bands_in`, a band whose
// record is NotFound (not done yet) leaves its rows zero too, and
// `bands_in` counts those that were there (a frame in progress).
Result<CostBuffer> stitch_cost(const FrameReady& frame,
                               const std::function<Result<std::string_view>(int band)>& record,
                               int* bands_in = nullptr);
// Writes the image as job_dir/file_name through a temporary name (the
// extension kept, by which write_image picks the format), fsyncing file and
// directory when `sync`.
Status write_frame_file(const std::string& job_dir, const std::string& file_name,
                        const Image& image, bool sync, bool sync_dir = true);
// The frame's file from its bands' records, as write_frame_file writes it:
// a PNG whose bands are all png8+deflate is joined from their bytes
// (png_from_bands: no pixel is decoded or compressed by the coordinator),
// an EXR whose bands are all exr+zip from their blocks
// (exr_blocks_from_bands); any other frame is stitched (stitch_frame) and
// encoded. A frame with a
// cost map (FrameReady::cost_file_name) has it written first, from
// stitch_cost, as the picture cost_map_image makes. With `sync` the
// file is fsynced before its rename, and the directory after it unless
// `sync_dir` is false (the caller syncs it once for several frames:
// sync_directory). `how`, when given, says which way it was written: the
// file's bytes are the same either way.
enum class FrameWrite { kJoined, kEncoded };
Status write_frame(const std::string& job_dir, const FrameReady& f,
                   const std::function<Result<std::string>(int band)>& record, bool sync,
                   bool sync_dir = true, FrameWrite* how = nullptr);
Status sync_directory(const std::string& dir);
}  // namespace locus::farm
