// The farm's vocabulary as plain C++ types, shared by the coordinator's
// scheduling logic, the worker's rendering logic and the CLI. No gRPC here:
// proto/wire/rpc.h converts between these and proto/locus.proto.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/base/image.h"
#include "common/base/labels.h"
#include "common/base/params.h"
#include "common/base/status.h"
#include "common/farm/band_codec.h"
#include "common/scene/scene.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus::farm {

using SteadyClock = std::chrono::steady_clock;
using TimePoint = SteadyClock::time_point;
using Millis = std::chrono::milliseconds;
// Injected wherever time matters, so tests drive leases with a fake clock.
using NowFn = std::function<TimePoint()>;

// The limits a coordinator enforces on every job (docs/farm.md "Limits"):
// the defaults of its flags, and the most the flags allow.
inline constexpr int kMaxFramesPerJob = 100000;
inline constexpr int64_t kMaxBandsPerJob = 1000000;

struct Limits {
  int max_resolution = kMaxResolution;  // pixels per side (--max-resolution)
  int max_objects = 100000;             // objects in a scene (--max-objects)
  int max_frames = kMaxFramesPerJob;    // frames per job (--max-frames)
  int64_t max_bands = kMaxBandsPerJob;  // frames x bands per job (--max-bands)
  int max_jobs = 1000;                  // jobs queued or running at once (--max-jobs)
};
// gRPC's message size limit, set explicitly on every server and channel; a
// band's pixels must fit in one message with room to spare.
inline constexpr int kMaxMessageBytes = 64 << 20;
inline constexpr int64_t kMaxBandBytes = 48 << 20;

// How every pixel is computed; the names are those of the CLI flags.
// `--aa` of `locus render` and of jobs that do not say: multi-scanning
// with 4 sub-scanlines per pixel row (issue #6).
inline constexpr int kDefaultAa = 4;

// Defaults are those of `locus render`: configuration IV.
struct RenderSettings {
  std::string method = "local";
  std::string boxes = "eye+shadow";
  int spp = 1;
  // local only: sub-scanlines per pixel row, 0 = point sampling; -1: the
  // method's default (kDefaultAa for local).
  int aa = -1;
  double tess_tol = kDefaultTessTol;  // pixels (--tess-tol)
};

// The settings as RenderParams: the names through kMethodLabels and
// kBoxesLabels (empty: the default above), spp 0 as 1, aa -1 as the
// method's default; then check_render_params(), the renderer's one check.
// The thread count is the worker's own.
Result<RenderParams> to_render_params(const RenderSettings& settings, int threads);
RenderSettings from_render_params(const RenderParams& params);

// kPaused: `locus pause`; no new leases, bands in flight finish and are
// kept; `locus resume` makes it queued or running again.
enum class JobState { kQueued, kRunning, kSucceeded, kFailed, kCancelled, kPaused };
// The names of `locus status`, the metrics' `state` label and the job
// store's `state` column (which parses them back).
inline constexpr Labels<JobState, 6> kJobStateLabels = {{{JobState::kQueued, "queued"},
                                                         {JobState::kRunning, "running"},
                                                         {JobState::kSucceeded, "succeeded"},
                                                         {JobState::kFailed, "failed"},
                                                         {JobState::kCancelled, "cancelled"},
                                                         {JobState::kPaused, "paused"}}};
// A C string: every name in the table (and the fallback) is a literal.
inline const char* job_state_name(JobState state) {
  return label_name(kJobStateLabels, state).data();
}
inline bool is_terminal(JobState s) {
  return s == JobState::kSucceeded || s == JobState::kFailed || s == JobState::kCancelled;
}

// A job's priority (`locus submit --priority`, `locus priority`): higher
// first (docs/farm.md "Priorities and fair share").
inline constexpr int kMinPriority = 0;
inline constexpr int kMaxPriority = 100;
inline constexpr int kDefaultPriority = 50;

// The order in which a job's frames are first leased (`--frame-order`):
// in order, or the first, middle and last frames before the others, so an
// artist can check a shot before the rest comes in.
enum class FrameOrder { kInOrder, kFirstMiddleLast };
inline constexpr Labels<FrameOrder, 2> kFrameOrderLabels = {
    {{FrameOrder::kInOrder, "in-order"}, {FrameOrder::kFirstMiddleLast, "first-middle-last"}}};

// What a job makes: frames, rendered band by band by the workers; or a
// movie of another job's frames, made by the coordinator once they are all
// written (docs/farm.md "Movies"; common/farm/movie.h).
enum class JobKind { kRender, kMovie };
inline constexpr Labels<JobKind, 2> kJobKindLabels = {
    {{JobKind::kRender, "render"}, {JobKind::kMovie, "movie"}}};

// A validated job as the scheduler sees it. The scene itself lives in the
// coordinator's scene store under `scene_hash`.
struct JobSpec {
  std::string scene_hash;
  std::string scene_name;
  RenderSettings render;
  int width = 0;
  int height = 0;
  int frame_first = 1;
  int frame_last = 1;
  int bands = 1;       // per frame, 1..height
  std::string output;  // file-name pattern, e.g. "shot_####.png"
  double orbit_degrees = 0;
  // Row edges of the bands, bands + 1 of them from 0 to height, when the
  // coordinator split by predicted cost (common/farm/band_split.h); empty:
  // equal heights (band_rows(height, bands, i)).
  std::vector<int> band_edges;
  // The cost-aware split's prediction of each row's cost (relative units;
  // common/farm/band_split.h), for the dashboard's band map; empty when
  // none was made (equal bands, the ray tracer).
  std::vector<float> row_costs;
  int priority = kDefaultPriority;
  FrameOrder frame_order = FrameOrder::kInOrder;
  // A band leased longer than this is taken back and retried elsewhere;
  // 0: the coordinator's --band-timeout.
  Millis band_timeout{0};
  // The user who submitted it (the name of the client token); empty: a
  // farm without named tokens, or a job stored before owners existed.
  std::string owner;
  // Pools: the job's bands go only to workers carrying all these tags.
  std::vector<std::string> require;
  // Dependencies: the job waits until these jobs have succeeded, and fails
  // if one of them fails or is cancelled.
  std::vector<std::string> after;
  // kRender: the movie to make of the frames once they are written (a
  // file name such as "shot.mp4"; empty: none), at `fps` frames a second;
  // it becomes a job of its own, of kind kMovie, after this one.
  // kMovie: `output` is the movie's file name, `after` the render job's
  // id alone, `fps` its rate; one "frame" (1), the movie, and no bands.
  JobKind kind = JobKind::kRender;
  std::string movie;
  int fps = 0;
  // POSTed the job's final status (JSON) when it ends; empty: nobody.
  std::string notify_url;
  // The cost maps' file-name pattern ("cost_####.png", written beside the
  // frames; docs/cost-map.md "On the farm"); empty: none. Its bands are
  // leased with BandLease::cost_map.
  std::string cost_map;

  int frames() const { return frame_last - frame_first + 1; }
  int64_t bands_total() const { return static_cast<int64_t>(frames()) * bands; }
};

// Rows of band `index` when `height` rows are cut into `bands` bands: as
// equal as integers allow, every row in exactly one band.
Band band_rows(int height, int bands, int index);
// Rows of band `index` of a job: its band_edges if it has them.
Band band_rows(const JobSpec& spec, int index);
// Rows of band `index` cut at `edges` (bands + 1 of them), or of equal
// heights if `edges` is empty.
Band band_rows(int height, int bands, const std::vector<int>& edges, int index);
// band_edges as text ("0 12 30 ... 512") and back; from_text checks that
// there are bands + 1 strictly increasing edges from 0 to height, and
// returns an empty vector (equal split) for empty text.
std::string band_edges_text(const std::vector<int>& edges);
Result<std::vector<int>> band_edges_from_text(const std::string& text, int height, int bands);

// The default split when a job does not give --bands: enough bands to keep
// every worker busy with several each, fewer per frame when the frames
// themselves give the parallelism, and at least enough that every band fits
// in one message.
// `cost_counts`: the bands carry their cost counts too (JobSpec::cost_map).
int default_bands(int width, int height, int frames, int workers, bool cost_counts = false);
// The fewest bands whose pixels each fit in kMaxBandBytes: 12 bytes a
// pixel (the floats, the largest encoding), and with `cost_counts` the
// counts' kCostCountBytes more, in case they do not compress.
int min_bands(int width, int height, bool cost_counts = false);

// The band encodings beyond those of every release that a worker offers
// (RegisterRequest.encodings; band_codec.h): png8+deflate for PNG jobs,
// exr+zip for EXR jobs.
struct EncodingOffers {
  bool png_deflate = false;
  bool exr_zip = false;
};

// A band leased to a worker: everything a stateless worker needs but the
// scene, which it fetches once per hash. On the wire it is v1::BandTask,
// the name of an older release (a band is never called a task in code).
struct BandLease {
  std::string lease_id;
  Millis lease_remaining{0};
  std::string job_id;
  std::string scene_hash;
  int frame = 0;
  int band = 0;
  int y0 = 0;
  int y1 = 0;
  int width = 0;
  int height = 0;
  RenderSettings render;
  double orbit_degrees = 0;
  int frame_first = 0;
  int frame_last = 0;
  // How the worker returns the pixels: band_encoding_for(the job's output).
  BandEncoding encoding = BandEncoding::kFloat32;
  // Return the band's work per pixel too (BandOutput::cost): the job makes
  // cost maps.
  bool cost_map = false;
};

// What a worker returns for a band: its pixels (linear RGB floats, rows
// y0..y1-1) or the error that prevented them.
struct BandOutput {
  std::string worker_id;
  std::string lease_id;
  std::vector<float> rgb;
  // The pixels as they travel, in the lease's encoding (band_codec.h): the
  // worker encodes rgb into it and sends it instead; the coordinator checks
  // it (check_band) and keeps it as it came. Empty bytes with kFloat32: the
  // pixels are in rgb alone (the lease asked for floats, or the worker is of
  // an older release).
  EncodedBand encoded;
  // Set by the coordinator when `encoded` does not decode: the problem. The
  // scheduler charges such a result as it charges pixels of the wrong size.
  std::string malformed;
  Stats stats;
  // With BandLease::cost_map: the band's work per pixel, encode_band_cost's
  // bytes; empty: none (not asked, or a worker of an older release).
  std::string cost;
  std::string error;
  bool handed_back = false;  // the worker is stopping and gives the band back unrendered
  // What the worker logged for the band (BandLogCapture), kept with the job.
  std::vector<std::string> log_lines;
};

// Band-seconds of a job's attempts (lease to end), apart by how they ended:
// accepted, failed (charged to the band), lost (a race lost, lapsed,
// revoked, preempted, handed back, voided by a restart).
struct BandSeconds {
  double done = 0;
  double failed = 0;
  double lost = 0;
};

struct JobInfo {
  std::string job_id;
  JobState state = JobState::kQueued;
  JobSpec spec;
  int64_t bands_done = 0;
  int frames_done = 0;  // stitched and written
  std::vector<int> frames_written;
  std::string error;
  double seconds_elapsed = 0;
  Stats stats;
  int64_t results_discarded = 0;   // results that lost a race to another lease of their band
  int64_t speculative_leases = 0;  // second leases of bands running far longer than their peers
  std::vector<std::string> quarantined;  // worker names that get no more bands of this job
  int64_t bands_timed_out = 0;           // leases taken back by the band timeout (a hung band)
  int64_t bands_running = 0;             // live leases (a speculated band counts twice)
  // Why no band of it runs although some wait: "waiting for job j0003
  // (running)", "waiting for a worker tagged bigmem"; empty otherwise.
  std::string waiting;
  BandSeconds account;  // the CPU seconds of accepted results are stats.seconds_render_cpu
  // A render job's movie job (JobSpec::movie), once made; empty: none.
  std::string movie_job;
};

struct WorkerInfo {
  std::string worker_id;
  std::string name;
  int threads = 1;
  std::vector<std::string> tags;  // `locus-worker --tag`
  // The encodings it offers (RegisterRequest.encodings): jobs' bands are
  // leased to it in them (band_encoding_for).
  EncodingOffers encodings;
  bool draining = false;          // `locus drain`: finishes its band, takes no more, exits
  bool disabled = false;          // `locus disable`: by name, until `locus enable`
  bool busy = false;
  std::string job_id;  // of the band in hand
  int frame = 0;
  int band = 0;
  int64_t bands_done = 0;
  double seconds_since_seen = 0;
};

// A line of a job's history (`locus events`), as the coordinator's job store keeps it.
struct HistoryEntry {
  int64_t seq = 0;  // increasing over the store's life: a cursor for --follow
  double at = 0;    // Unix seconds
  int frame = -1;   // the band's, or -1 for the whole job
  int band = -1;
  std::string text;
};
// A line a worker logged for a band (`locus logs`).
struct BandLogLine {
  int64_t seq = 0;  // a cursor, as HistoryEntry::seq
  int frame = 0;
  int band = 0;
  std::string lease_id;
  std::string worker_id;
  std::string text;
};
// One lease of a band as the store remembers it (the dashboard's band map
// and worker page).
struct AttemptInfo {
  std::string lease_id;
  std::string job_id;
  int frame = 0;
  int band = 0;
  std::string worker_id;
  std::string worker_name;
  bool speculative = false;
  double started_at = 0;  // Unix seconds
  double ended_at = 0;    // 0: still leased
  std::string outcome;    // kLeaseOutcomeLabels' word, "void"; empty: still leased
  std::string error;
};
// A band of one frame: where it stands, who rendered it, what it cost.
struct BandDetail {
  int band = 0;
  int y0 = 0;
  int y1 = 0;
  std::string state;          // "queued", "running" or "done"
  double predicted_cost = 0;  // the sum of its rows' JobSpec::row_costs; 0: none
  Stats stats;                // of the accepted result
  double seconds = 0;         // lease to result, of the accepted result
  std::string worker_id;      // of the accepted result, or of the live lease
  std::string worker_name;
  std::vector<AttemptInfo> attempts;  // oldest first
};
struct FrameDetail {
  std::string job_id;
  int frame = 0;
  int width = 0;
  int height = 0;
  bool written = false;
  std::string file_name;
  std::vector<BandDetail> bands;
  std::vector<float> row_costs;  // JobSpec::row_costs
};
// A worker's recent work: connected (`info` set) or remembered by the store.
struct WorkerDetail {
  std::optional<WorkerInfo> info;
  std::string worker_id;
  std::vector<AttemptInfo> attempts;  // newest first
  std::vector<BandLogLine> logs;      // newest first
};

// The most history or log lines one ListEvents or ListLogs call returns
// (the client pages).
inline constexpr int kMaxEventsPerCall = 10000;

// The worker's state as `locus workers` and the wire name it.
inline const char* worker_state_name(const WorkerInfo& w) {
  return w.disabled ? "disabled" : w.draining ? "draining" : w.busy ? "busy" : "idle";
}

// A frame whose bands are all in their band files, ready to be stitched
// and written (server/band_files.h).
struct FrameReady {
  std::string job_id;
  int frame = 0;
  std::string file_name;
  int width = 0;
  int height = 0;
  int bands = 0;
  std::vector<int> band_edges;  // as JobSpec::band_edges
  // The frame's cost map's file name (JobSpec::cost_map); empty: none.
  std::string cost_file_name;
};
// Frame `frame` of job `job_id`, whose bands are all in.
FrameReady frame_ready(const std::string& job_id, const JobSpec& spec, int frame);

// The state of the farm at one moment (Scheduler::counts()), for the
// metrics' gauges.
struct FarmCounts {
  int64_t bands_queued = 0;   // waiting for a worker
  int64_t bands_running = 0;  // under a lease (a speculated band counts once)
  int64_t bands_done = 0;     // of the jobs the coordinator holds
  std::array<int64_t, kJobStateLabels.size()> jobs{};  // by JobState
  int64_t workers = 0;                                 // registered and not dropped
};

// A submission as the client sends it, before validation.
struct SubmitRequest {
  v1::Scene scene;
  std::string scene_name;
  RenderSettings render;
  int width = 0;  // 0: the scene camera's
  int height = 0;
  int frame_first = 1;
  int frame_last = 1;
  int bands = 0;  // 0: default_bands()
  std::string output;
  double orbit_degrees = 0;
  int priority = kDefaultPriority;
  std::string frame_order;           // a kFrameOrderLabels name; empty: in order
  Millis band_timeout{0};            // 0: the coordinator's
  std::vector<std::string> require;  // worker tags
  std::vector<std::string> after;    // job ids
  std::string movie;                 // JobSpec::movie: a file name; empty: no movie
  int fps = 0;                       // of the movie; 0: kDefaultFps
  std::string notify_url;            // JobSpec::notify_url
  std::string cost_map;              // JobSpec::cost_map: a file-name pattern; empty: none
  // The client's token for this submission, reused on retries: a second
  // submission with the same id returns the first one's job.
  std::string request_id;
};

struct Registration {
  std::string worker_id;
  Millis heartbeat{0};
  Millis lease{0};
};

struct FileChunk {
  int frame = 0;
  std::string file_name;
  int64_t offset = 0;
  std::string data;
  bool last = false;
};

// Worker tags and the tags a job requires: at most kMaxTags each, names of
// 1..64 letters, digits, '_', '-' and '.'. InvalidArgument naming `what`
// ("--tag", "require") and the tag.
inline constexpr size_t kMaxTags = 16;
// The most jobs one job may wait for (--after).
inline constexpr size_t kMaxAfter = 64;
Status check_tags(const std::vector<std::string>& tags, const std::string& what);
// Tags (or job ids) as one line, "a b c", and back (the job store's columns).
std::string words_text(const std::vector<std::string>& words);
std::vector<std::string> words_from_text(const std::string& text);

// Hex SHA-256: scenes are addressed by the hash of their serialized form.
std::string content_hash(std::string_view bytes);

// The frame's still scene exactly as every renderer of the farm builds it:
// the resolution set, then scene_at_frame() with the job's orbit. The
// in-process `locus render --workers 0` calls it too.
Scene frame_scene(Scene base, int width, int height, int frame, int frame_first,
                  int frame_last, double orbit_degrees);
// frame_scene(base, ...).camera, without a copy of base's objects: where the
// frames share their geometry (AnimationGeometry), a frame needs no more.
Camera frame_camera(const Scene& base, int width, int height, int frame, int frame_first,
                    int frame_last, double orbit_degrees);

}  // namespace locus::farm
