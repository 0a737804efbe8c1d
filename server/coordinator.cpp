#include "server/coordinator.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <tuple>

#include "common/base/image.h"
#include "common/base/log.h"
#include "common/farm/band_split.h"
#include "common/scene/animation.h"
#include "server/await.h"
#include "server/band_files.h"
#include "server/metrics.h"
#include "server/submission.h"
#include "server/syncs.h"

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

constexpr size_t kChunkBytes = 1 << 20;

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options)
    : options_(std::move(options)),
      scheduler_(SchedulerOptions{options_.lease, options_.lease, options_.max_attempts,
                                  options_.quarantine_after, options_.speculate_factor,
                                  options_.speculate_min, options_.band_timeout, options_.ageing,
                                  options_.user_max_running, options_.exr_zip},
                 options_.now),
      metrics_(std::make_unique<CoordinatorMetrics>()) {}

Coordinator::~Coordinator() { shutdown(); }

Status Coordinator::start() {
  std::error_code ec;
  fs::create_directories(fs::path(options_.data_dir) / "jobs", ec);
  if (ec)
    return FailedPrecondition("--data " + options_.data_dir + ": cannot create: " + ec.message());
  fs::create_directories(output_root(), ec);
  if (ec)
    return FailedPrecondition("--output-root " + output_root() +
                              ": cannot create: " + ec.message());
  std::lock_guard lk(mu_);
  if (started_) return Status::Ok();
  if (Status s = recover(); !s.ok()) return s;
  started_ = true;
  ticker_ = std::thread([this] { tick_loop(); });
  int writers = options_.frame_writers;
  if (writers <= 0)
    writers = static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
  for (int i = 0; i < writers; ++i) writers_.emplace_back([this] { write_loop(); });
  movie_maker_ = std::thread([this] { movie_loop(); });
  dispatcher_ = std::thread([this] { dispatch_loop(); });
  committer_ = std::thread([this] { commit_loop(); });
  return Status::Ok();
}

Status Coordinator::recover() {
  // One coordinator per data directory: a second one would resume the same
  // jobs and hand out the same bands. The lock goes with the process, so a
  // killed coordinator never leaves it behind.
  const std::string lock = (fs::path(options_.data_dir) / "coordinator.lock").string();
  lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0) return FailedPrecondition(lock + ": cannot open: " + std::strerror(errno));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    return FailedPrecondition("--data " + options_.data_dir +
                              " is in use by another coordinator; give each its own directory");
  }
  const std::string db = (fs::path(options_.data_dir) / "locus.db").string();
  auto store = JobStore::open(db, options_.fsync);
  if (!store.ok()) return store.status();
  store_ = std::move(*store);
  auto state = store_->recover();
  if (!state.ok()) return Status(Code::kFailedPrecondition, db + ": " + state.status().message());
  std::error_code ec;
  for (RecoveredJob& j : state->jobs) {
    const std::string dir = job_dir(j.record.job_id);
    const JobSpec& s = j.record.spec;
    // 0.13 kept each band in a file of its own, under <job>/bands/: a done
    // band whose record is not in the store is imported from its file.
    const fs::path legacy = fs::path(dir) / "bands";
    const bool has_legacy = fs::is_directory(legacy, ec);
    if (j.state == JobState::kSucceeded) {
      // Bands of a job that succeeded are of no more use (left by a crash).
      // Those of a failed or cancelled job stay for `locus retry`.
      if (has_legacy) fs::remove_all(legacy, ec);
      continue;
    }
    const std::set<int> written(j.frames_written.begin(), j.frames_written.end());
    // A band is done only if its record is whole (its checksum, its rows):
    // a record damaged on disk, or (after a power loss) a store ahead of
    // the disk, and the band is rendered again.
    std::vector<RecoveredJob::BandRef> kept;
    for (const RecoveredJob::BandRef& b : j.done_bands) {
      if (written.count(b.frame)) continue;
      const Band rows = band_rows(s, b.band);
      const BandPixels pixels{s.width, rows.y0, rows.y1};
      auto record = store_->band_record(j.record.job_id, b.frame, b.band);
      const bool from_legacy =
          !record.ok() && record.status().code() == Code::kNotFound && has_legacy;
      if (from_legacy) record = read_band_file(band_file_path(dir, b.frame, b.band));
      const bool whole = record.ok() && unpack_band(*record, pixels).ok();
      if (whole && from_legacy) {
        if (Status st = store_->put_band_record(j.record.job_id, b.frame, b.band, *record);
            !st.ok()) {
          return st;
        }
      }
      if (whole) {
        kept.push_back(b);
      } else {
        const std::string why = from_legacy   ? "its 0.13 band file is missing or damaged"
                                : record.ok() ? "its record is damaged (checksum or size)"
                                              : record.status().message();
        spdlog::warn("job {}: band {} of frame {}: {}; rendering it again", j.record.job_id, b.band,
                     b.frame, why);
        if (Status st = store_->forget_band(j.record.job_id, b.frame, b.band); !st.ok()) return st;
        --j.bands_done;
      }
    }
    if (has_legacy) fs::remove_all(legacy, ec);
    j.done_bands = std::move(kept);
    if (is_terminal(j.state)) continue;
    if (Status st = load_scene(s.scene_hash, j.record.job_id); !st.ok())
      return FailedPrecondition(db + ": " + st.message());
  }
  for (FrameReady& f : scheduler_.restore(*state)) to_write_.push_back(std::move(f));
  // Ends still to be told when the previous run stopped.
  for (const RecoveredJob& j : state->jobs) {
    if (!j.notify_pending || !job_ended_ || !is_terminal(j.state)) continue;
    if (auto info = scheduler_.job(j.record.job_id); info.ok()) job_ended_(*info);
  }
  for (const auto& [hash, scene] : scenes_) scenes_stored_.insert(hash);
  if (!state->jobs.empty()) {
    spdlog::info("job store {}: {} jobs, {} leases of the previous run voided, {} frames to write",
                 db, state->jobs.size(), state->leases_voided, to_write_.size());
  }
  return Status::Ok();
}

void Coordinator::on_job_ended(std::function<void(const JobInfo&)> fn, bool every_job) {
  std::lock_guard lk(mu_);
  job_ended_ = std::move(fn);
  notify_every_job_ = every_job;
}

void Coordinator::record_notified(const std::string& job_id, const std::string& text, bool done) {
  std::lock_guard lk(mu_);
  if (crashed_ || !store_) return;
  const event::JobNotified e{job_id, done ? event::NotifyPhase::kDone : event::NotifyPhase::kNote,
                             text};
  if (Status s = store_->apply({e}); !s.ok()) spdlog::error("{}", s.message());
}

LatencySummary Coordinator::dispatch_latency() {
  std::lock_guard lk(mu_);
  return dispatch_.summary();
}

void Coordinator::refresh_metrics() {
  std::lock_guard lk(mu_);
  metrics_->set_counts(scheduler_.counts());
  metrics_->set_syncs(sync_counts());
}

std::string Coordinator::metrics_text() {
  refresh_metrics();
  return farm::metrics_text(*metrics_->registry());
}

void Coordinator::drain() {
  {
    std::lock_guard lk(mu_);
    if (draining_) return;
    draining_ = true;
  }
  spdlog::info("draining: no new jobs, no new leases; waiting for the bands in flight");
  changed_.notify_all();
}

bool Coordinator::wait_drained(Millis max) {
  std::unique_lock lk(mu_);
  const bool drained = changed_.wait_for(lk, max, [&] {
    return stopping_ ||
           (scheduler_.counts().bands_running == 0 && to_write_.empty() && writing_.empty());
  });
  const FarmCounts c = scheduler_.counts();
  if (drained) {
    spdlog::info("drained: no band in flight, every finished frame written");
  } else {
    spdlog::warn(
        "drain: {} bands still in flight after {} ms; their leases are voided by the "
        "next start on this data directory",
        c.bands_running, max.count());
  }
  return drained;
}

void Coordinator::stop_waiting() {
  {
    std::lock_guard lk(mu_);
    closing_ = true;
  }
  changed_.notify_all();
}

void Coordinator::shutdown() {
  {
    std::lock_guard lk(mu_);
    if (stopping_) return;
    stopping_ = true;
  }
  changed_.notify_all();
  write_ready_.notify_all();
  commit_ready_.notify_all();
  if (ticker_.joinable()) ticker_.join();
  if (dispatcher_.joinable()) dispatcher_.join();
  // The last batch is committed (and its frames queued) before the writer
  // writes the last frames.
  if (committer_.joinable()) committer_.join();
  write_ready_.notify_all();
  for (std::thread& w : writers_) {
    if (w.joinable()) w.join();
  }
  if (movie_maker_.joinable()) movie_maker_.join();
  std::lock_guard lk(mu_);
  const LatencySummary d = dispatch_.summary();
  if (d.count > 0) {
    spdlog::info("dispatch latency: {} bands, p50 {:.0f} us, p99 {:.0f} us, max {:.0f} us", d.count,
                 d.p50_us, d.p99_us, d.max_us);
  }
  // What bench/farm/scale.sh reads for "syncs per band" (server/syncs.h).
  const SyncCounts syncs = sync_counts();
  spdlog::info("syncs: {} (the store's {}, the coordinator's files' {})", syncs.total(),
               syncs.store, syncs.files);
  persist();
  store_.reset();
  close_store_files();
  if (lock_fd_ >= 0) ::close(lock_fd_);
  lock_fd_ = -1;
}

void Coordinator::crash_for_test() {
  {
    std::lock_guard lk(mu_);
    if (stopping_) return;
    stopping_ = true;
    crashed_ = true;
    to_write_.clear();
    scheduler_.take_events();
  }
  changed_.notify_all();
  write_ready_.notify_all();
  commit_ready_.notify_all();
  if (ticker_.joinable()) ticker_.join();
  if (dispatcher_.joinable()) dispatcher_.join();
  // The last batch is committed (and its frames queued) before the writer
  // writes the last frames.
  if (committer_.joinable()) committer_.join();
  write_ready_.notify_all();
  for (std::thread& w : writers_) {
    if (w.joinable()) w.join();
  }
  if (movie_maker_.joinable()) movie_maker_.join();
  // Closing the connection checkpoints nothing that a reopen would not
  // recover from the WAL anyway.
  std::lock_guard lk(mu_);
  store_.reset();
  close_store_files();
  if (lock_fd_ >= 0) ::close(lock_fd_);
  lock_fd_ = -1;
}

std::string Coordinator::job_dir(const std::string& job_id) const {
  return (fs::path(output_root()) / job_id).string();
}

std::string Coordinator::output_root() const {
  return options_.output_root.empty() ? (fs::path(options_.data_dir) / "jobs").string()
                                      : options_.output_root;
}

// ---------------------------------------------------------------- background

void Coordinator::tick_loop() {
  std::unique_lock lk(mu_);
  uint64_t seen = scheduler_.version();
  auto retained = SteadyClock::now() - std::chrono::hours(1);
  while (!stopping_) {
    // Its own rhythm: woken by every change it would run once per band.
    changed_.wait_for(lk, options_.tick, [&] { return stopping_; });
    std::set<std::string> arrived;
    {
      std::lock_guard a(arrivals_mu_);
      arrived.swap(arrivals_);
    }
    for (const std::string& id : arrived) (void)scheduler_.touch(id);  // or dropped already
    scheduler_.expire();
    persist();
    check_storage();
    if (SteadyClock::now() - retained >= options_.retention_check) {
      retained = SteadyClock::now();
      apply_retention();
    }
    if (scheduler_.version() != seen) {
      seen = scheduler_.version();
      drop_unused_scenes();
      changed_.notify_all();
    }
  }
}

void Coordinator::worker_call_arrived(const std::string& worker_id) {
  if (worker_id.empty() || worker_id.size() > 256) return;  // checked by the handler
  std::lock_guard lk(arrivals_mu_);
  arrivals_.insert(worker_id);
}

void Coordinator::drop_unused_scenes() {
  // In memory the scenes of unfinished jobs; in the store every job's, for
  // a retry or a requeue, until the job is deleted.
  const std::set<std::string> used = scheduler_.scenes_in_use();
  for (auto it = scenes_.begin(); it != scenes_.end();) {
    it = used.count(it->first) ? std::next(it) : scenes_.erase(it);
  }
  const std::set<std::string> kept = scheduler_.scenes_kept();
  if (store_ && kept != scenes_stored_) {
    if (Status s = store_->keep_scenes(kept); s.ok()) {
      scenes_stored_ = kept;
    } else {
      spdlog::error("{}", s.message());
    }
  }
}

Status Coordinator::load_scene(const std::string& hash, const std::string& job_id) {
  if (scenes_.count(hash)) return Status::Ok();
  auto bytes = store_->scene(hash);
  // Its content hash checks it; workers parse it.
  if (!bytes.ok() || content_hash(*bytes) != hash) {
    return FailedPrecondition("the scene of job " + job_id +
                              " is missing or unreadable in the job store");
  }
  scenes_.emplace(hash, std::make_shared<const std::string>(std::move(*bytes)));
  return Status::Ok();
}

bool Coordinator::write_pending(const std::string& job_id, int frame) const {
  const auto same = [&](const FrameReady& f) { return f.job_id == job_id && f.frame == frame; };
  return std::any_of(writing_.begin(), writing_.end(), same) ||
         std::any_of(to_write_.begin(), to_write_.end(), same) ||
         std::any_of(held_frames_.begin(), held_frames_.end(), same);
}

void Coordinator::write_loop() {
  // The frames waiting, up to kFrameBatch, are written one after the other,
  // each file synced before its rename; then each of their directories is
  // synced once, and only then does the store say "written" (which deletes
  // their band records): a sync per frame, and one per directory per batch
  // rather than per frame.
  constexpr size_t kFrameBatch = 16;
  std::unique_lock lk(mu_);
  for (;;) {
    write_ready_.wait(lk, [&] { return stopping_ || !to_write_.empty(); });
    if (to_write_.empty()) return;  // stopping, and nothing left
    // Several writer threads: each takes the oldest frames waiting.
    std::vector<std::list<FrameReady>::iterator> mine;
    while (!to_write_.empty() && mine.size() < kFrameBatch) {
      writing_.push_back(std::move(to_write_.front()));
      to_write_.pop_front();
      mine.push_back(std::prev(writing_.end()));
    }
    std::vector<FrameReady> frames;
    for (const auto& it : mine) frames.push_back(*it);
    lk.unlock();
    // Bounded memory: each writer thread holds one frame image at a time,
    // stitched from the band records and freed before the next.
    // Its bands' records are read through the writer's own connection:
    // committed (the group commit queued the frame after its transaction).
    std::vector<Status> written;
    std::vector<std::string> dirs;
    for (const FrameReady& f : frames) {
      dirs.push_back(job_dir(f.job_id));
      written.push_back(write_frame(
          dirs.back(), f, [&](int band) { return read_band_record(f.job_id, f.frame, band); },
          options_.fsync, /*sync_dir=*/false));
    }
    if (options_.fsync) {
      std::set<std::string> synced;
      for (size_t i = 0; i < frames.size(); ++i) {
        if (!written[i].ok() || synced.count(dirs[i])) continue;
        const Status s = sync_directory(dirs[i]);
        synced.insert(dirs[i]);
        for (size_t k = i; k < frames.size(); ++k) {
          if (dirs[k] == dirs[i] && written[k].ok()) written[k] = s;
        }
      }
    }
    lk.lock();
    // Once the store says "written" it deletes the frame's band records, in
    // the same transaction (JobStore, event::FrameWritten). A frame that
    // found no space waits for it.
    for (size_t i = 0; i < frames.size(); ++i) {
      if (!hold_frame(frames[i], written[i])) {
        scheduler_.frame_written(frames[i].job_id, frames[i].frame, written[i]);
      }
    }
    persist();
    for (const auto& it : mine) writing_.erase(it);
    changed_.notify_all();
  }
}

// ---------------------------------------------------------------- clients

Result<JobInfo> Coordinator::submit(const SubmitRequest& r, const std::string& owner) {
  Result<CheckedSubmission> job = check_submission(r, options_.limits, options_.mesh_root);
  if (!job.ok()) return job.status();
  job->spec.owner = owner;
  // The scene as the workers will get it, addressed by its content hash.
  auto bytes = std::make_shared<std::string>();
  r.scene.SerializeToString(bytes.get());
  job->spec.scene_hash = content_hash(*bytes);
  const std::string fingerprint = submission_fingerprint(r, job->spec);
  bool cost_split = false;
  {
    std::lock_guard lk(mu_);
    if (auto answer = refused_or_retried(r, *job, fingerprint)) return *answer;
    if (Status s = count_bands(r.bands, *job); !s.ok()) return s;
    cost_split = options_.cost_bands && job->spec.bands > 1 &&
                 (options_.always_cost_bands ||
                  cost_split_pays(job->spec.bands, static_cast<int>(scheduler_.worker_count())));
  }
  // The cost pre-pass outside mu_: it renders a preview of the scene
  // (seconds for a big one), and every worker's lease, result and
  // heartbeat waits on mu_.
  if (cost_split) job->spec.band_edges = options_.cost_pass(*job, &job->spec.row_costs);
  // An EXR job's bands on its frames' blocks: each worker compresses its
  // own, and the frame is written from them (band_codec.h "exr+zip").
  if (output_sample_format(job->spec.output) == SampleFormat::kFloat32) {
    job->spec.band_edges =
        align_band_edges(job->spec.height, job->spec.bands, job->spec.band_edges);
  }
  std::lock_guard lk(mu_);
  // Asked again: meanwhile a retry of this request may have been recorded,
  // a drain begun or the queue filled.
  if (auto answer = refused_or_retried(r, *job, fingerprint)) return *answer;
  return record_job(job->spec, std::move(bytes), r.request_id, fingerprint);
}

std::optional<Result<JobInfo>> Coordinator::refused_or_retried(const SubmitRequest& r,
                                                               const CheckedSubmission& job,
                                                               const std::string& fingerprint) {
  if (stopping_ || draining_) {
    return Status(Code::kUnavailable,
                  "the coordinator is shutting down; submit again once it is back");
  }
  if (Status s = storage_refusal("new jobs are refused"); !s.ok()) return s;
  if (const uint64_t avail = free_bytes(); avail < options_.min_free_bytes) {
    return Status(Code::kResourceExhausted,
                  "the coordinator's data directory " + options_.data_dir + " has " +
                      std::to_string(avail >> 20) + " MiB free, under its --min-free-mb " +
                      std::to_string(options_.min_free_bytes >> 20) +
                      ": new jobs are refused until space is freed");
  }
  if (auto earlier = scheduler_.job_for_request(r.request_id)) {
    return resubmitted(*earlier, r.request_id, fingerprint);
  }
  if (Status s = scheduler_.check_after(job.spec.after); !s.ok()) return s;
  if (!job.spec.notify_url.empty()) {
    if (Status s = check_notify_url(job.spec.notify_url, options_.notify_urls); !s.ok()) return s;
  }
  const int max_jobs = options_.limits.max_jobs;
  if (scheduler_.unfinished_jobs() >= static_cast<size_t>(max_jobs)) {
    return Status(Code::kResourceExhausted,
                  "the farm already has " + std::to_string(max_jobs) +
                      " jobs queued or running (--max-jobs); wait for one to end, or cancel one");
  }
  return std::nullopt;
}

Result<JobInfo> Coordinator::resubmitted(const JobRecord& earlier, const std::string& request_id,
                                         const std::string& fingerprint) {
  if (earlier.fingerprint != fingerprint) {
    return Status(Code::kAlreadyExists,
                  "request id '" + request_id + "' was already used for another submission (job " +
                      earlier.job_id + "); a new submission needs a new request id");
  }
  spdlog::info("job {}: submission retried (request id {})", earlier.job_id, request_id);
  return scheduler_.job(earlier.job_id);
}

Status Coordinator::count_bands(int bands, CheckedSubmission& job) {
  JobSpec& spec = job.spec;
  spec.bands = bands > 0 ? bands
                         : default_bands(spec.width, spec.height, spec.frames(),
                                         static_cast<int>(scheduler_.worker_count()),
                                         !spec.cost_map.empty());
  if (spec.bands_total() > options_.limits.max_bands) {
    return InvalidArgument(std::to_string(spec.frames()) + " frames x " +
                           std::to_string(spec.bands) + " bands: at most " +
                           std::to_string(options_.limits.max_bands) +
                           " bands per job (--max-bands)");
  }
  return Status::Ok();
}

Result<JobInfo> Coordinator::record_job(const JobSpec& spec,
                                        std::shared_ptr<const std::string> scene,
                                        const std::string& request_id,
                                        const std::string& fingerprint) {
  // Recorded before the client hears of the job: an id the client was
  // given survives any restart.
  if (Status st = store_->put_scene(spec.scene_hash, *scene); !st.ok()) {
    return Status(Code::kUnavailable, "cannot record the job: " + st.message());
  }
  // What is pending first, so that a failure below holds this job's events
  // only, which are then dropped with the job.
  if (Status st = persist(); !st.ok()) {
    return Status(Code::kUnavailable, "cannot record the job: " + st.message());
  }
  scenes_stored_.insert(spec.scene_hash);
  // With a movie, its notification goes with the movie job (the end of it all).
  JobSpec render = spec;
  if (!spec.movie.empty()) render.notify_url.clear();
  const std::string id = scheduler_.add_job(render, request_id, fingerprint);
  // The movie job in the same transaction: both jobs or neither.
  const std::string movie_id =
      spec.movie.empty() ? std::string() : scheduler_.add_job(movie_spec(spec, id));
  if (Status st = persist(); !st.ok()) {
    unstored_.clear();
    if (!movie_id.empty()) scheduler_.forget_job(movie_id);
    scheduler_.forget_job(id);
    return Status(Code::kUnavailable, "cannot record the job: " + st.message());
  }
  scenes_.emplace(spec.scene_hash, std::move(scene));
  spdlog::info("job {}: {} {}x{} frames {}-{} x {} bands -> {}", id, spec.scene_name, spec.width,
               spec.height, spec.frame_first, spec.frame_last, spec.bands, spec.output);
  if (!movie_id.empty()) {
    spdlog::info("job {}: the movie {} of job {} at {} fps", movie_id, spec.movie, id, spec.fps);
  }
  changed_.notify_all();
  return scheduler_.job(id);
}

Status Coordinator::may_read(const JobInfo& job, const Caller& caller) const {
  const std::string& owner = job.spec.owner;
  if (!options_.private_jobs || owner.empty() || caller.admin || caller.user == owner)
    return Status::Ok();
  return Status(Code::kPermissionDenied, "job " + job.job_id + " belongs to " + owner +
                                             "; jobs are private on this farm (--private-jobs)");
}

Result<JobInfo> Coordinator::job(const std::string& job_id, const Caller& caller) {
  std::lock_guard lk(mu_);
  auto r = scheduler_.job(job_id);
  if (r.ok()) {
    if (Status s = may_read(*r, caller); !s.ok()) return s;
  }
  return r;
}

std::vector<JobInfo> Coordinator::jobs(const Caller& caller) {
  std::lock_guard lk(mu_);
  std::vector<JobInfo> all = scheduler_.jobs();
  std::erase_if(all, [&](const JobInfo& j) { return !may_read(j, caller).ok(); });
  return all;
}

Result<JobInfo> Coordinator::act(const std::string& job_id, const char* what, const Caller& caller,
                                 const std::function<Result<JobInfo>(const std::string&)>& call) {
  std::lock_guard lk(mu_);
  auto job = scheduler_.job(job_id);
  if (!job.ok()) return job.status();
  const std::string& owner = job->spec.owner;
  if (!owner.empty() && !caller.admin && caller.user != owner) {
    return Status(Code::kPermissionDenied,
                  "job " + job_id + " belongs to " + owner + "; " +
                      (caller.user.empty() ? "an unnamed user" : caller.user) + " may not " + what +
                      " it (only its owner or an admin)");
  }
  // The history names the caller: the user, "admin NAME" acting on another's job.
  const std::string who = caller.admin && !caller.user.empty() && caller.user != owner
                              ? "admin " + caller.user
                              : caller.user;
  auto r = call(who);
  if (r.ok()) spdlog::info("job {}: {}{}", job_id, what, who.empty() ? "" : " by " + who);
  persist();
  changed_.notify_all();
  return r;
}

Result<JobInfo> Coordinator::cancel(const std::string& job_id, const Caller& caller) {
  return act(job_id, "cancel", caller,
             [&](const std::string& who) { return scheduler_.cancel(job_id, who); });
}

Result<JobInfo> Coordinator::set_priority(const std::string& job_id, int priority, bool preempt,
                                          const Caller& caller) {
  return act(job_id, "reprioritise", caller, [&](const std::string& who) {
    return scheduler_.set_priority(job_id, priority, preempt, who);
  });
}

Result<JobInfo> Coordinator::reopen(const std::string& job_id,
                                    const std::function<Result<Scheduler::Reopened>()>& call) {
  auto j = scheduler_.job(job_id);
  if (!j.ok()) return j.status();
  if (is_terminal(j->state)) {
    if (stopping_ || draining_) {
      return Status(Code::kUnavailable,
                    "the coordinator is shutting down; try again once it is back");
    }
    const int max_jobs = options_.limits.max_jobs;
    if (scheduler_.unfinished_jobs() >= static_cast<size_t>(max_jobs)) {
      return Status(Code::kResourceExhausted,
                    "the farm has " + std::to_string(max_jobs) +
                        " unfinished jobs (--max-jobs); try again when one has finished");
    }
    if (Status s = load_scene(j->spec.scene_hash, job_id); !s.ok()) {
      return FailedPrecondition(s.message() + " (the job ended before its scene was kept); " +
                                "submit it again");
    }
  }
  auto r = call();
  if (!r.ok()) return r.status();
  // A frame the job finished before it ended may still be on its way to
  // the writer: it is written once.
  for (FrameReady& f : r->ready) {
    if (!write_pending(f.job_id, f.frame)) to_write_.push_back(std::move(f));
  }
  write_ready_.notify_one();
  return r->info;
}

Result<JobInfo> Coordinator::retry(const std::string& job_id, const Caller& caller) {
  return act(job_id, "retry", caller, [&](const std::string& who) {
    return reopen(job_id, [&] { return scheduler_.retry(job_id, who); });
  });
}

Result<JobInfo> Coordinator::requeue(const std::string& job_id, std::optional<int> first,
                                     std::optional<int> last, const Caller& caller) {
  return act(job_id, "requeue", caller, [&](const std::string& who) {
    return reopen(job_id, [&] { return scheduler_.requeue(job_id, first, last, who); });
  });
}

Result<JobInfo> Coordinator::pause(const std::string& job_id, const Caller& caller) {
  return act(job_id, "pause", caller,
             [&](const std::string& who) { return scheduler_.pause(job_id, who); });
}

Result<JobInfo> Coordinator::resume(const std::string& job_id, const Caller& caller) {
  return act(job_id, "resume", caller,
             [&](const std::string& who) { return scheduler_.resume(job_id, who); });
}

namespace {
Status admin_only(const Caller& caller, const char* what) {
  if (caller.admin) return Status::Ok();
  return Status(Code::kPermissionDenied,
                std::string("only an admin may ") + what + " workers (--admin-tokens); " +
                    (caller.user.empty() ? "this caller" : caller.user) + " is not one");
}
}  // namespace

Result<std::string> Coordinator::drain_worker(const std::string& worker, const Caller& caller) {
  if (Status s = admin_only(caller, "drain"); !s.ok()) return s;
  std::lock_guard lk(mu_);
  auto r = scheduler_.drain_worker(worker);
  if (!r.ok()) return r.status();
  polls_all_ = true;
  changed_.notify_all();  // its long poll, if any, returns at once and says so
  return r->name;
}

Result<std::string> Coordinator::set_worker_disabled(const std::string& worker, bool disabled,
                                                     const Caller& caller) {
  if (Status s = admin_only(caller, disabled ? "disable" : "enable"); !s.ok()) return s;
  std::lock_guard lk(mu_);
  auto r = scheduler_.set_disabled(worker, disabled);
  persist();
  changed_.notify_all();
  return r;
}

bool Coordinator::worker_draining(const std::string& worker_id) {
  std::lock_guard lk(mu_);
  return scheduler_.draining(worker_id);
}

Status Coordinator::remove_job(const JobInfo& job, bool outputs) {
  if (!is_terminal(job.state)) {
    return FailedPrecondition("job " + job.job_id + " is " + job_state_name(job.state) +
                              "; cancel it first, then delete it");
  }
  persist();
  if (Status s = store_->delete_job(job.job_id); !s.ok()) return s;
  scheduler_.forget_job(job.job_id);
  std::error_code ec;
  const fs::path dir = job_dir(job.job_id);
  fs::remove_all(outputs ? dir : dir / "bands", ec);
  fs::remove_all(dir / ".dashboard", ec);  // the dashboard's cached images
  if (ec) spdlog::warn("job {}: cannot remove {}: {}", job.job_id, dir.string(), ec.message());
  spdlog::info("job {}: deleted{}", job.job_id, outputs ? " with its frames" : "");
  return Status::Ok();
}

Result<JobInfo> Coordinator::delete_job(const std::string& job_id, bool outputs,
                                        const Caller& caller) {
  return act(job_id, "delete", caller, [&](const std::string&) -> Result<JobInfo> {
    auto j = scheduler_.job(job_id);
    if (!j.ok()) return j.status();
    if (Status s = remove_job(*j, outputs); !s.ok()) return s;
    return j;
  });
}

void Coordinator::apply_retention() {
  if (options_.retention.count() <= 0 || !store_) return;
  const double before = wall_now() - std::chrono::duration<double>(options_.retention).count();
  auto old = store_->jobs_finished_before(before);
  if (!old.ok()) {
    spdlog::error("retention: {}", old.status().message());
    return;
  }
  for (const std::string& id : *old) {
    auto j = scheduler_.job(id);
    if (!j.ok()) continue;
    if (Status s = remove_job(*j, true); !s.ok()) spdlog::error("retention: {}", s.message());
  }
}

Result<std::vector<BandLogLine>> Coordinator::logs(const std::string& job_id, int frame, int band,
                                                   int64_t after, int limit, const Caller& caller) {
  std::lock_guard lk(mu_);
  auto j = scheduler_.job(job_id);
  if (!j.ok()) return j.status();
  if (Status s = may_read(*j, caller); !s.ok()) return s;
  if (!store_) return FailedPrecondition("the coordinator has no job store (not started)");
  return store_->band_logs(job_id, frame, band, after, limit);
}

Result<std::vector<HistoryEntry>> Coordinator::events(const std::string& job_id, int64_t after,
                                                      int limit, const Caller& caller) {
  std::lock_guard lk(mu_);
  auto j = scheduler_.job(job_id);
  if (!j.ok()) return j.status();
  if (Status s = may_read(*j, caller); !s.ok()) return s;
  if (!store_) return FailedPrecondition("the coordinator has no job store (not started)");
  return store_->history(job_id, after, limit);
}

std::vector<WorkerInfo> Coordinator::workers() {
  std::lock_guard lk(mu_);
  return scheduler_.workers();
}

Status Coordinator::watch(const std::string& job_id, const Caller& caller, Millis max,
                          const CancelledFn& cancelled, const JobSink& sink) {
  const auto end = SteadyClock::now() + std::clamp(max, Millis(0), options_.max_watch);
  std::unique_lock lk(mu_);
  // The version is the whole scheduler's: skip updates that left this job
  // as it was.
  std::optional<std::tuple<JobState, int64_t, int>> sent;
  for (;;) {
    Result<JobInfo> info = scheduler_.job(job_id);
    if (!info.ok()) return info.status();
    if (Status s = may_read(*info, caller); !s.ok()) return s;
    const uint64_t seen = scheduler_.version();
    lk.unlock();
    const auto now = std::make_tuple(info->state, info->bands_done, info->frames_done);
    if (sent != now) {
      if (!sink(*info)) return Status::Ok();
      sent = now;
    }
    if (is_terminal(info->state)) return Status::Ok();
    const auto next = SteadyClock::now() + options_.watch_interval;
    lk.lock();
    // Throttle, then wait for a change; wake regularly to notice a client
    // that went away. The job's end is sent at once, not after the
    // throttle (a `locus render` waits for it).
    changed_.wait_until(lk, std::min(next, end),
                        [&] { return stopping_ || closing_ || scheduler_.job_ended(job_id); });
    while (!stopping_ && !closing_ && scheduler_.version() == seen && SteadyClock::now() < end) {
      if (cancelled && cancelled()) return Status::Ok();
      changed_.wait_for(lk, Millis(200));
    }
    if (stopping_ || closing_)
      return Status(Code::kUnavailable, "the coordinator is shutting down");
    if (SteadyClock::now() >= end) {
      auto last = scheduler_.job(job_id);
      lk.unlock();
      if (last.ok()) sink(*last);
      return Status::Ok();
    }
  }
}

Status Coordinator::fetch(const std::string& job_id, const Caller& caller,
                          const std::vector<int>& frames, const ChunkSink& sink, bool cost_maps) {
  JobInfo info;
  {
    std::lock_guard lk(mu_);
    auto r = scheduler_.job(job_id);
    if (!r.ok()) return r.status();
    if (Status s = may_read(*r, caller); !s.ok()) return s;
    info = *r;
  }
  if (cost_maps && info.spec.cost_map.empty()) {
    return FailedPrecondition("job " + job_id + " makes no cost maps (submit it with --cost-map)");
  }
  std::vector<int> want = frames.empty() ? info.frames_written : frames;
  std::sort(want.begin(), want.end());
  const std::set<int> written(info.frames_written.begin(), info.frames_written.end());
  for (int f : want) {
    if (!written.count(f)) {
      return NotFound("frame " + std::to_string(f) + " of job " + job_id + " is not written (job " +
                      job_state_name(info.state) + ", " + std::to_string(info.frames_done) +
                      " of " + std::to_string(info.spec.frames()) + " frames written)");
    }
  }
  std::vector<char> buf(kChunkBytes);
  for (int f : want) {
    const std::string name = frame_path(cost_maps ? info.spec.cost_map : info.spec.output, f);
    const fs::path path = fs::path(job_dir(job_id)) / name;
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      return Internal(path.string() + ": cannot read the written " +
                      (cost_maps ? "cost map" : "frame"));
    }
    int64_t offset = 0;
    for (;;) {
      in.read(buf.data(), buf.size());
      const std::streamsize n = in.gcount();
      FileChunk c;
      c.frame = f;
      c.file_name = name;
      c.offset = offset;
      c.data.assign(buf.data(), static_cast<size_t>(n));
      c.last = !in;
      offset += n;
      if (!sink(c)) return Status(Code::kCancelled, "the client stopped reading");
      if (c.last) break;
    }
  }
  return Status::Ok();
}

}  // namespace locus::farm
