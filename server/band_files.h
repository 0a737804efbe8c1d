// Pixels on the coordinator's disk: each accepted band in its own band file,
// each finished frame as an image, both written atomically (a temporary
// file, fsync when asked, rename). A frame is stitched from its band files
// when its last band is in, so the coordinator holds one frame in memory at
// a time however many frames are in progress. Layout under DATA/jobs/<job>/:
//   bands/<frame>-<band>.band   accepted bands of frames not yet written
//   <file>                      the written frames (shot_0007.png)
#pragma once

#include <string>
#include <vector>

#include "common/base/image.h"
#include "common/base/status.h"
#include "common/farm/types.h"

namespace locus::farm {

std::string band_file_path(const std::string& job_dir, int frame, int band);

// The rows [y0, y1) of a `width`-pixel-wide frame: linear RGB floats.
struct BandPixels {
  int width = 0;
  int y0 = 0;
  int y1 = 0;
};

// Writes the pixels to a temporary file beside the band's file (unique to
// `tag`, e.g. the lease id) and fsyncs it when `sync`. Returns its path;
// commit_band_file() renames it into place.
Result<std::string> write_band_temp(const std::string& job_dir, int frame, int band,
                                    const BandPixels& rows, const std::vector<float>& rgb,
                                    const std::string& tag, bool sync);
Status commit_band_file(const std::string& temp, const std::string& path);
// The pixels of a band file, checked against the expected rows and its
// checksum: a torn or foreign file is an error, never pixels.
Result<std::vector<float>> read_band_file(const std::string& path, const BandPixels& rows);

// Reads the frame's band files into one image.
Result<Image> stitch_frame(const std::string& job_dir, const FrameReady& frame);
// Writes the image as job_dir/file_name through a temporary name (the
// extension kept, by which OpenImageIO picks the format), fsyncing file and
// directory when `sync`.
Status write_frame_file(const std::string& job_dir, const std::string& file_name,
                        const Image& image, bool sync);
// Removes the band files of a written frame, and temporaries left by a crash.
void remove_band_files(const std::string& job_dir, int frame, int bands);
void remove_band_temporaries(const std::string& job_dir);

}  // namespace locus::farm
