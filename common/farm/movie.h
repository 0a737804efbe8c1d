// Movies of a job's frames (`--movie out.mp4`, docs/farm.md "Movies"):
// the checks of a movie's name and rate, shared by the CLI and the
// coordinator, and assemble_movie(), which runs Debian's ffmpeg on written
// frames. On a farm the movie is a job of its own (JobKind::kMovie) that
// waits for the render job and that the coordinator runs itself;
// `locus render --workers 0` calls assemble_movie() directly. No network.
#pragma once

#include <functional>
#include <string>
#include <string_view>

#include "common/base/status.h"
#include "common/farm/types.h"

namespace locus::farm {

inline constexpr int kDefaultFps = 24;
inline constexpr int kMaxFps = 240;
// The longest one ffmpeg run may take before it is killed (a wedged
// encoder must not hold the movie step for ever).
inline constexpr Millis kMovieTimeout{30 * 60 * 1000};

// What the movie's file name asks for: H.264 in MP4 (yuv420p, so that
// every player shows it), VP9 in WebM, or an animated GIF preview.
enum class MovieFormat { kMp4, kWebm, kGif };

// The format of "shot.mp4" / ".webm" / ".gif" (case-insensitive);
// InvalidArgument naming `what` (the flag) and the name otherwise.
Result<MovieFormat> movie_format(std::string_view name, const std::string& what);

// A movie request: `movie` a plain file name with a known extension (its
// directories are the client's), `fps` in [1, kMaxFps] (0: kDefaultFps),
// frames written as PNG or TIFF (`frames_output`, the job's -o pattern:
// linear EXR frames would need a tone curve a movie does not have).
// InvalidArgument naming the flag and the problem.
Status check_movie(const std::string& movie, int fps, const std::string& frames_output);

// One movie to make: frames [first, last] named by `pattern` (with its
// #### field) in `frames_dir`, shown at `fps`, written to `out_path`
// atomically (a complete file or none).
struct MovieInput {
  std::string frames_dir;
  std::string pattern;
  int first = 1;
  int last = 1;
  int fps = kDefaultFps;
  std::string out_path;
};

// Runs ffmpeg ($LOCUS_FFMPEG, else `ffmpeg` on the PATH) on the frames.
// Returns the movie's size in bytes. FailedPrecondition when a frame is
// missing or ffmpeg is not installed; Internal with ffmpeg's last error
// line when it fails; Cancelled when `cancelled()` turns true (polled
// every 50 ms: ffmpeg is killed) or DeadlineExceeded after `timeout`.
Result<int64_t> assemble_movie(const MovieInput& input, const std::function<bool()>& cancelled,
                               Millis timeout = kMovieTimeout);

}  // namespace locus::farm
