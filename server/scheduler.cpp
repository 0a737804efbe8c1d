#include "server/scheduler.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <random>

#include "common/animation.h"

namespace locus::farm {
namespace {

double seconds(SteadyClock::duration d) { return std::chrono::duration<double>(d).count(); }

std::string numbered(const char* prefix, uint64_t n) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%s%04llu", prefix, static_cast<unsigned long long>(n));
  return buf;
}

}  // namespace

Scheduler::Scheduler(SchedulerOptions options, NowFn now)
    : options_(options), now_(std::move(now)) {
  // Lease ids never repeat across coordinator runs: a result carrying a
  // lease from an earlier run must read as stale, not as some new lease.
  std::random_device rd;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%08x-", rd());
  lease_prefix_ = buf;
}

// ---------------------------------------------------------------- jobs

std::string Scheduler::add_job(JobSpec spec) {
  const std::string id = numbered("j", next_job_++);
  Job job;
  job.info.job_id = id;
  job.info.state = JobState::kQueued;
  job.info.spec = std::move(spec);
  job.submitted = now_();
  job.tasks.resize(job.info.spec.bands_total());
  for (int i = 0; i < static_cast<int>(job.tasks.size()); ++i) job.queue.push_back(i);
  jobs_.emplace(id, std::move(job));
  order_.push_back(id);
  ++version_;
  return id;
}

Scheduler::Job* Scheduler::find_job(const std::string& id) {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}

const Scheduler::Job* Scheduler::find_job(const std::string& id) const {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}

JobInfo Scheduler::snapshot(const Job& job) const {
  JobInfo info = job.info;
  const TimePoint end = is_terminal(job.info.state) ? job.finished : now_();
  info.seconds_elapsed = seconds(end - job.submitted);
  return info;
}

Result<JobInfo> Scheduler::job(const std::string& job_id) const {
  const Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  return snapshot(*job);
}

std::vector<JobInfo> Scheduler::jobs() const {
  std::vector<JobInfo> out;
  for (const std::string& id : order_) out.push_back(snapshot(jobs_.at(id)));
  return out;
}

void Scheduler::drop_leases_of(Job& job) {
  for (auto it = leases_.begin(); it != leases_.end();) {
    if (it->second.job_id == job.info.job_id) {
      auto w = workers_.find(it->second.worker_id);
      if (w != workers_.end()) w->second.leases.erase(it->first);
      it = leases_.erase(it);
    } else {
      ++it;
    }
  }
  job.queue.clear();
  job.partial.clear();
}

void Scheduler::fail_job(Job& job, const std::string& error) {
  if (is_terminal(job.info.state)) return;
  spdlog::warn("job {} failed: {}", job.info.job_id, error);
  job.info.state = JobState::kFailed;
  job.info.error = error;
  job.finished = now_();
  drop_leases_of(job);
  ++version_;
}

Result<JobInfo> Scheduler::cancel(const std::string& job_id) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  if (!is_terminal(job->info.state)) {
    job->info.state = JobState::kCancelled;
    job->finished = now_();
    drop_leases_of(*job);
    ++version_;
  }
  return snapshot(*job);
}

void Scheduler::frame_written(const std::string& job_id, int frame, const Status& status) {
  Job* job = find_job(job_id);
  if (!job || is_terminal(job->info.state)) return;
  if (!status.ok()) {
    fail_job(*job, "frame " + std::to_string(frame) + ": " + status.message());
    return;
  }
  ++job->info.frames_done;
  job->info.frames_written.push_back(frame);
  if (job->info.frames_done == job->info.spec.frames()) {
    job->info.state = JobState::kSucceeded;
    job->finished = now_();
    spdlog::info("job {} succeeded in {:.3f} s ({} frames, {} bands)", job_id,
                 seconds(job->finished - job->submitted), job->info.spec.frames(),
                 job->info.spec.bands_total());
  }
  ++version_;
}

// ---------------------------------------------------------------- workers

std::string Scheduler::add_worker(const std::string& name, int threads) {
  const std::string id = numbered("w", next_worker_++);
  Worker w;
  w.info.worker_id = id;
  w.info.name = name;
  w.info.threads = threads;
  w.last_seen = now_();
  workers_.emplace(id, std::move(w));
  ++version_;
  return id;
}

Status Scheduler::touch(const std::string& worker_id) {
  auto it = workers_.find(worker_id);
  if (it == workers_.end()) {
    return NotFound(
        "worker '" + worker_id +
        "' is unknown (dropped after silence, or the coordinator restarted); register again");
  }
  it->second.last_seen = now_();
  return Status::Ok();
}

std::vector<WorkerInfo> Scheduler::workers() const {
  std::vector<WorkerInfo> out;
  const TimePoint now = now_();
  for (const auto& [id, w] : workers_) {
    WorkerInfo info = w.info;
    info.busy = !w.leases.empty();
    if (info.busy) {
      const Lease& l = leases_.at(*w.leases.begin());
      const Job& job = jobs_.at(l.job_id);
      info.job_id = l.job_id;
      info.frame = job.info.spec.frame_first + l.task / job.info.spec.bands;
      info.band = l.task % job.info.spec.bands;
    }
    info.seconds_since_seen = seconds(now - w.last_seen);
    out.push_back(std::move(info));
  }
  return out;
}

std::set<std::string> Scheduler::scenes_in_use() const {
  std::set<std::string> used;
  for (const auto& [id, job] : jobs_) {
    if (!is_terminal(job.info.state)) used.insert(job.info.spec.scene_hash);
  }
  return used;
}

size_t Scheduler::unfinished_jobs() const {
  return static_cast<size_t>(std::count_if(jobs_.begin(), jobs_.end(), [](const auto& kv) {
    return !is_terminal(kv.second.info.state);
  }));
}

bool Scheduler::has_queued_bands() const {
  for (const auto& [id, job] : jobs_) {
    if (!is_terminal(job.info.state) && !job.queue.empty()) return true;
  }
  return false;
}

BandTask Scheduler::make_task(const Job& job, int task, const Lease& lease) const {
  const JobSpec& s = job.info.spec;
  BandTask t;
  t.lease_id = job.tasks[task].lease_id;
  t.lease_remaining = std::chrono::duration_cast<Millis>(lease.deadline - now_());
  t.job_id = job.info.job_id;
  t.scene_hash = s.scene_hash;
  t.frame = s.frame_first + task / s.bands;
  t.band = task % s.bands;
  const Band rows = band_rows(s.height, s.bands, t.band);
  t.y0 = rows.y0;
  t.y1 = rows.y1;
  t.width = s.width;
  t.height = s.height;
  t.render = s.render;
  t.orbit_degrees = s.orbit_degrees;
  t.frame_first = s.frame_first;
  t.frame_last = s.frame_last;
  return t;
}

Result<std::optional<BandTask>> Scheduler::next_task(const std::string& worker_id) {
  const Status alive = touch(worker_id);
  if (!alive.ok()) return alive;
  Worker& worker = workers_.at(worker_id);
  for (const std::string& id : order_) {
    Job& job = jobs_.at(id);
    if (is_terminal(job.info.state) || job.queue.empty()) continue;
    const int task = job.queue.front();
    job.queue.pop_front();
    Task& t = job.tasks[task];
    t.state = TaskState::kLeased;
    ++t.attempts;
    t.lease_id = lease_prefix_ + std::to_string(next_lease_++);
    Lease lease{id, task, worker_id, now_() + options_.lease};
    leases_.emplace(t.lease_id, lease);
    worker.leases.insert(t.lease_id);
    if (job.info.state == JobState::kQueued) job.info.state = JobState::kRunning;
    ++version_;
    return std::optional<BandTask>(make_task(job, task, lease));
  }
  return std::optional<BandTask>();
}

Result<std::vector<std::string>> Scheduler::heartbeat(const std::string& worker_id,
                                                      const std::vector<std::string>& lease_ids) {
  const Status alive = touch(worker_id);
  if (!alive.ok()) return alive;
  std::vector<std::string> revoked;
  const TimePoint now = now_();
  for (const std::string& id : lease_ids) {
    auto it = leases_.find(id);
    if (it == leases_.end() || it->second.worker_id != worker_id || it->second.deadline < now) {
      revoked.push_back(id);
      continue;
    }
    it->second.deadline = now + options_.lease;
  }
  return revoked;
}

void Scheduler::release(const std::string& lease_id, const std::string& why, bool charge) {
  auto it = leases_.find(lease_id);
  if (it == leases_.end()) return;
  const Lease lease = it->second;
  leases_.erase(it);
  auto w = workers_.find(lease.worker_id);
  if (w != workers_.end()) w->second.leases.erase(lease_id);
  Job* job = find_job(lease.job_id);
  if (!job || is_terminal(job->info.state)) return;
  Task& t = job->tasks[lease.task];
  if (t.state != TaskState::kLeased || t.lease_id != lease_id) return;
  t.state = TaskState::kQueued;
  t.lease_id.clear();
  t.last_error = why;
  if (!charge) --t.attempts;
  ++version_;
  const JobSpec& s = job->info.spec;
  if (t.attempts >= options_.max_attempts) {
    fail_job(*job, "band " + std::to_string(lease.task % s.bands) + " of frame " +
                       std::to_string(s.frame_first + lease.task / s.bands) + " failed " +
                       std::to_string(t.attempts) + " times; last: " + why);
    return;
  }
  spdlog::info("job {}: band {} of frame {} back in the queue: {}", lease.job_id,
               lease.task % s.bands, s.frame_first + lease.task / s.bands, why);
  job->queue.push_front(lease.task);
}

Result<CompleteOutcome> Scheduler::complete_band(BandOutput out) {
  const Status alive = touch(out.worker_id);
  if (!alive.ok()) return alive;
  CompleteOutcome outcome;
  auto it = leases_.find(out.lease_id);
  if (it == leases_.end() || it->second.worker_id != out.worker_id) {
    outcome.reason =
        "lease '" + out.lease_id + "' is not held by this worker (lapsed, re-leased or cancelled)";
    return outcome;
  }
  if (it->second.deadline < now_()) {
    // Strict: once the deadline has passed the band may already be leased
    // elsewhere as far as any observer can tell; the first valid result wins.
    release(out.lease_id, "lease of worker " + out.worker_id + " lapsed", true);
    outcome.reason = "lease '" + out.lease_id + "' lapsed before the result arrived";
    return outcome;
  }
  const Lease lease = it->second;
  Job& job = jobs_.at(lease.job_id);
  const JobSpec& s = job.info.spec;
  if (!out.error.empty()) {
    release(out.lease_id, "worker " + out.worker_id + ": " + out.error, true);
    outcome.accepted = true;
    return outcome;
  }
  const int band = lease.task % s.bands;
  const int frame = s.frame_first + lease.task / s.bands;
  const Band rows = band_rows(s.height, s.bands, band);
  const size_t expected = static_cast<size_t>(s.width) * (rows.y1 - rows.y0) * 3;
  if (out.rgb.size() != expected) {
    const std::string why = "band " + std::to_string(band) + " of frame " + std::to_string(frame) +
                            ": expected " + std::to_string(expected) + " floats (" +
                            std::to_string(s.width) + " x " + std::to_string(rows.y1 - rows.y0) +
                            " x 3), got " + std::to_string(out.rgb.size());
    release(out.lease_id, "worker " + out.worker_id + " sent malformed pixels: " + why, true);
    return InvalidArgument(why);
  }

  // Allocate before any state changes: if the frame's memory cannot be had,
  // the lease stands and lapses like any other, and the job stays coherent.
  PartialFrame& pf = job.partial[frame];
  if (pf.image.width == 0) pf.image = Image(s.width, s.height);

  leases_.erase(it);
  workers_.at(out.worker_id).leases.erase(out.lease_id);
  workers_.at(out.worker_id).info.bands_done++;
  Task& t = job.tasks[lease.task];
  t.state = TaskState::kDone;
  t.lease_id.clear();
  job.info.bands_done++;
  job.info.stats += out.stats;

  std::copy(out.rgb.begin(), out.rgb.end(),
            pf.image.rgb.begin() + static_cast<size_t>(rows.y0) * s.width * 3);
  ++pf.bands_done;
  outcome.accepted = true;
  if (pf.bands_done == s.bands) {
    FrameImage f;
    f.job_id = job.info.job_id;
    f.frame = frame;
    f.file_name = frame_path(s.output, frame);
    f.image = std::move(pf.image);
    job.partial.erase(frame);
    job.stitched.insert(frame);
    outcome.frame = std::move(f);
  }
  ++version_;
  return outcome;
}

void Scheduler::expire() {
  const TimePoint now = now_();
  std::vector<std::string> gone;
  for (const auto& [id, w] : workers_) {
    if (now - w.last_seen > options_.worker_timeout) gone.push_back(id);
  }
  for (const std::string& id : gone) {
    spdlog::warn("worker {} ({}) silent for {:.1f} s: dropped", id, workers_.at(id).info.name,
                 seconds(now - workers_.at(id).last_seen));
    const std::set<std::string> held = workers_.at(id).leases;
    for (const std::string& l : held) release(l, "worker " + id + " went silent", true);
    workers_.erase(id);
    ++version_;
  }
  std::vector<std::string> lapsed;
  for (const auto& [id, l] : leases_) {
    if (l.deadline < now) lapsed.push_back(id);
  }
  for (const std::string& id : lapsed) {
    release(id, "lease of worker " + leases_.at(id).worker_id + " lapsed", true);
  }
}

}  // namespace locus::farm
