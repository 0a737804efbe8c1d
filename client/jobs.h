// The CLI's jobs: what `locus render`, `validate` and `submit` do with a
// scene, in process or on an embedded local farm (client/local_farm.h),
// or on a running farm. main.cpp binds the flags and the other commands.
#pragma once

#include <string>
#include <vector>

#include "common/base/params.h"
#include "common/base/status.h"
#include "common/farm/auth.h"
#include "common/farm/types.h"

namespace locus::cli {

// Flags shared by `render` and `submit`: what to render and how.
struct JobArgs {
  std::string scene;
  std::string output;
  std::string size;
  // --method, --boxes, --spp, --aa, --tess-tol; configuration IV by
  // default (issue #5), aa -1: the method's default.
  farm::RenderSettings render;
  std::string frames;
  double orbit = 0;
  int bands = 0;
  // --movie: the frames as a movie (.mp4, .webm, .gif) at --fps, once all
  // are written (common/farm/movie.h).
  std::string movie;
  int fps = 0;
  // --cost-map: where the work went, per pixel (docs/cost-map.md); a
  // pattern like -o's for several frames. On a farm the workers count and
  // the coordinator writes it beside each frame; the client fetches it.
  std::string cost_map;
};

struct RenderArgs {
  JobArgs job;
  int threads = 0;
  bool threads_given = false;
  int workers = -1;  // -1: one per core
  bool workers_given = false;
  std::string stats;
  // --visibility: the local method's visible-surface pass (RenderParams);
  // anything but auto renders in process.
  std::string visibility{label_name(kVisibilityLabels, RenderParams{}.visibility)};
  // --shadows: configuration IV's shadows of scanned spans (RenderParams);
  // anything but the default renders in process.
  std::string shadows{label_name(kShadowPassLabels, RenderParams{}.shadows)};
};

struct SubmitArgs {
  JobArgs job;
  bool wait = false;
  int priority = farm::kDefaultPriority;
  std::string frame_order;
  double band_timeout = 0;  // seconds; 0: the coordinator's
  std::vector<std::string> require;
  std::vector<std::string> after;
  std::string notify_url;
};

// Prints "locus: message" on stderr; returns the exit status 1.
int fail(const std::string& message);
int fail(const Status& status);

// "A-B" or "A" (--frames); empty: frame 1.
Status parse_frames(const std::string& s, int* first, int* last);

// `locus render`: in process (--workers 0, a forced pass) or
// on an embedded local farm of `workers` worker processes.
int run_render(const RenderArgs& a);
// `locus validate`: the scene's problems, or a summary of it.
int run_validate(const std::string& path);
// `locus submit`: the job to the farm at `address`; with --wait, followed
// until its frames (and movie) are fetched.
int run_submit(const std::string& address, const farm::Credentials& creds, const SubmitArgs& a);

}  // namespace locus::cli
