#include "common/farm/movie.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include "common/base/image.h"
#include "common/farm/process.h"
#include "common/scene/animation.h"

namespace locus::farm {
namespace {

namespace fs = std::filesystem;

// The encoder's arguments after the input. Odd sizes are padded by a row
// or a column (yuv420p needs even ones); the RGB frames are converted with
// the BT.709 matrix and tagged so, which is what players assume of HD
// video and honour when tagged.
std::vector<std::string> encoder_args(MovieFormat format) {
  const std::string yuv =
      "pad=ceil(iw/2)*2:ceil(ih/2)*2,scale=out_color_matrix=bt709:out_range=tv,format=yuv420p";
  const std::vector<std::string> tags = {"-colorspace", "bt709", "-color_primaries", "bt709",
                                         "-color_trc",  "bt709", "-color_range",     "tv"};
  std::vector<std::string> a;
  switch (format) {
    case MovieFormat::kMp4:
      a = {"-vf", yuv, "-c:v", "libx264", "-preset", "medium", "-crf", "16", "-movflags",
           "+faststart"};
      a.insert(a.end(), tags.begin(), tags.end());
      a.insert(a.end(), {"-f", "mp4"});
      break;
    case MovieFormat::kWebm:
      a = {"-vf",       yuv,  "-c:v",      "libvpx-vp9", "-crf", "30", "-b:v", "0",
           "-deadline", "good", "-cpu-used", "4",          "-row-mt", "1"};
      a.insert(a.end(), tags.begin(), tags.end());
      a.insert(a.end(), {"-f", "webm"});
      break;
    case MovieFormat::kGif:
      // One palette for the whole movie, made from it (a GIF has 256 colours).
      a = {"-vf", "split[a][b];[a]palettegen=stats_mode=full[p];[b][p]paletteuse=dither=bayer",
           "-loop", "0", "-f", "gif"};
      break;
  }
  return a;
}

// A directory of links f000001.ext ... to the frames, so that ffmpeg reads
// a plain numbered sequence whatever the frames' names hold ('%' included).
Status link_frames(const MovieInput& in, const fs::path& dir, const std::string& ext) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Internal(dir.string() + ": cannot make the movie's work directory: " + ec.message());
  for (int f = in.first; f <= in.last; ++f) {
    const fs::path frame = fs::absolute(fs::path(in.frames_dir) / frame_path(in.pattern, f));
    if (!fs::is_regular_file(frame, ec)) {
      return FailedPrecondition("frame " + std::to_string(f) + " (" + frame.string() +
                                ") is missing: the movie needs every frame written");
    }
    char name[32];
    std::snprintf(name, sizeof name, "f%06d%s", f - in.first + 1, ext.c_str());
    fs::create_symlink(frame, dir / name, ec);
    if (ec) return Internal((dir / name).string() + ": cannot link a frame: " + ec.message());
  }
  return Status::Ok();
}

std::atomic<uint64_t> work_counter{0};

}  // namespace

Result<MovieFormat> movie_format(std::string_view name, const std::string& what) {
  const std::string ext = lower_extension(name);
  if (ext == ".mp4") return MovieFormat::kMp4;
  if (ext == ".webm") return MovieFormat::kWebm;
  if (ext == ".gif") return MovieFormat::kGif;
  return InvalidArgument(what + " " + std::string(name) +
                         ": a movie's name ends in .mp4 (H.264), .webm (VP9) or .gif");
}

Status check_movie(const std::string& movie, int fps, const std::string& frames_output) {
  if (movie.empty()) return Status::Ok();
  const std::string name = fs::path(movie).filename().string();
  if (name.empty() || name == "." || name == ".." || name != movie) {
    return InvalidArgument("movie '" + movie + "': a plain file name such as shot.mp4 (the farm "
                           "writes it beside the job's frames)");
  }
  if (name.find('#') != std::string::npos) {
    return InvalidArgument("movie '" + movie + "': one movie per job, no #### frame field");
  }
  if (auto f = movie_format(name, "movie"); !f.ok()) return f.status();
  if (fps < 0 || fps > kMaxFps) {
    return InvalidArgument("fps " + std::to_string(fps) + ": must be in [1, " +
                           std::to_string(kMaxFps) + "]");
  }
  const std::string ext = lower_extension(frames_output);
  if (ext != ".png" && ext != ".tif" && ext != ".tiff") {
    return InvalidArgument("movie " + movie + ": its frames must be PNG or TIFF (-o " +
                           frames_output + " writes " + (ext.empty() ? "no known type" : ext) +
                           "; EXR frames are linear and would need a tone curve)");
  }
  return Status::Ok();
}

Result<int64_t> assemble_movie(const MovieInput& in, const std::function<bool()>& cancelled,
                               Millis timeout) {
  auto format = movie_format(in.out_path, "movie");
  if (!format.ok()) return format.status();
  const fs::path out(in.out_path);
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  const std::string tag = std::to_string(::getpid()) + "." + std::to_string(++work_counter);
  // Hidden names beside the movie (GCC 12 misreads "." + string as an
  // overlapping copy, hence append).
  std::string hidden(1, '.');
  hidden.append(out.filename().string());
  const fs::path work = parent / (hidden + ".frames." + tag);
  const fs::path part = parent / (hidden + ".part." + tag);
  struct Cleanup {
    fs::path work, part;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(work, ec);
      fs::remove(part, ec);
    }
  } cleanup{work, part};

  const std::string ext = lower_extension(in.pattern);
  if (Status s = link_frames(in, work, ext); !s.ok()) return s;
  const char* env = std::getenv("LOCUS_FFMPEG");
  const std::string ffmpeg = env && *env ? env : "ffmpeg";
  std::vector<std::string> args = {ffmpeg,       "-nostdin",
                                   "-hide_banner", "-loglevel",
                                   "error",        "-y",
                                   "-framerate",   std::to_string(in.fps > 0 ? in.fps : kDefaultFps),
                                   "-start_number", "1",
                                   "-i",           (work / ("f%06d" + ext)).string()};
  for (std::string& a : encoder_args(*format)) args.push_back(std::move(a));
  args.push_back(part.string());

  ProcessRun run;
  run.argv = std::move(args);
  run.output_path = (work / "ffmpeg.log").string();
  run.timeout = timeout;
  run.cancelled = cancelled;
  auto ran = run_process(run);
  if (!ran.ok()) {
    if (ran.status().code() == Code::kNotFound) {
      return FailedPrecondition(ran.status().message() +
                                ": the movie needs ffmpeg (apt-get install ffmpeg)");
    }
    if (ran.status().code() == Code::kCancelled) {
      return Status(Code::kCancelled, "the movie was stopped");
    }
    return ran.status();
  }
  if (ran->exit_code == 127) {
    return FailedPrecondition("cannot run " + ffmpeg +
                              ": the movie needs ffmpeg (apt-get install ffmpeg)");
  }
  if (ran->exit_code != 0) {
    const std::string how = ran->exit_code > 0
                                ? "exited with status " + std::to_string(ran->exit_code)
                                : "was killed by signal " + std::to_string(ran->signal);
    return Internal("ffmpeg " + how + (ran->last_line.empty() ? "" : ": " + ran->last_line));
  }
  std::error_code ec;
  const auto size = fs::file_size(part, ec);
  if (ec || size == 0) return Internal("ffmpeg wrote no movie to " + part.string());
  fs::rename(part, out, ec);
  if (ec) return Internal(out.string() + ": cannot write the movie: " + ec.message());
  return static_cast<int64_t>(size);
}

}  // namespace locus::farm
