// The Scheduler (scheduler.h): its jobs. Its workers are in
// scheduler_workers.cpp, the dispatch of bands (leases, results, expiry) in
// scheduler_dispatch.cpp, movies, restore and reopen in their own files.
#include "server/scheduler.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <random>

#include "server/scheduler_internal.h"

namespace locus::farm {
using scheduler_detail::format_seconds;
using scheduler_detail::numbered;
using scheduler_detail::seconds;

bool is_charged(LeaseOutcome o) {
  return o == LeaseOutcome::kFailed || o == LeaseOutcome::kMalformed ||
         o == LeaseOutcome::kLapsed || o == LeaseOutcome::kSilent || o == LeaseOutcome::kTimedOut;
}

Scheduler::Scheduler(SchedulerOptions options, NowFn now)
    : options_(options), now_(std::move(now)) {
  // Lease ids never repeat across coordinator runs: a result carrying a
  // lease from an earlier run must read as stale, not as some new lease.
  std::random_device rd;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%08x-", rd());
  lease_prefix_ = buf;
}

std::string Scheduler::add_job(JobSpec spec, const std::string& request_id,
                               const std::string& fingerprint) {
  const uint64_t seq = next_job_++;
  const std::string id = numbered("j", seq);
  Job job;
  job.info.job_id = id;
  job.info.state = JobState::kQueued;
  job.info.spec = std::move(spec);
  job.record.job_id = id;
  job.record.seq = static_cast<int64_t>(seq);
  job.record.request_id = request_id;
  job.record.fingerprint = fingerprint;
  job.record.spec = job.info.spec;
  job.submitted = now_();
  job.waiting_since = job.submitted;
  job.bands.resize(job.info.spec.bands_total());
  events_.push_back(event::JobAdded{job.record});
  if (!request_id.empty()) requests_[request_id] = id;
  if (job.info.spec.kind == JobKind::kMovie && !job.info.spec.after.empty())
    movies_[job.info.spec.after.front()] = id;
  track(jobs_.emplace(id, std::move(job)).first->second);
  order_.push_back(id);
  ++version_;
  return id;
}

void Scheduler::forget_job(const std::string& job_id) {
  Job* job = find_job(job_id);
  if (!job) return;
  drop_leases_of(*job);
  if (!job->record.request_id.empty()) requests_.erase(job->record.request_id);
  movies_.erase(job_id);
  for (auto it = movies_.begin(); it != movies_.end();) {
    it = it->second == job_id ? movies_.erase(it) : std::next(it);
  }
  order_.erase(std::remove(order_.begin(), order_.end(), job_id), order_.end());
  live_.erase(job->record.seq);
  jobs_.erase(job_id);
  ++version_;
}

std::optional<JobRecord> Scheduler::job_for_request(const std::string& request_id) const {
  auto it = requests_.find(request_id);
  if (request_id.empty() || it == requests_.end()) return std::nullopt;
  return jobs_.at(it->second).record;
}

Scheduler::Job* Scheduler::find_job(const std::string& id) {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}

const Scheduler::Job* Scheduler::find_job(const std::string& id) const {
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : &it->second;
}

std::string Scheduler::band_name(const Job& job, int job_band) const {
  return "band " + std::to_string(band_of(job, job_band)) + " of frame " +
         std::to_string(frame_of(job, job_band));
}

JobInfo Scheduler::snapshot(const Job& job) const {
  JobInfo info = job.info;
  info.bands_running = job.running;
  info.waiting = waiting_reason(job);
  if (auto m = movies_.find(job.info.job_id); m != movies_.end()) info.movie_job = m->second;
  const TimePoint end = is_terminal(job.info.state) ? job.finished : now_();
  info.seconds_elapsed = seconds(end - job.submitted);
  return info;
}

std::string Scheduler::waiting_reason(const Job& job) const {
  const JobState st = job.info.state;
  if (is_terminal(st) || st == JobState::kPaused || job.running > 0) return "";
  if (const Job* before = waiting_for(job)) {
    return "waiting for job " + before->info.job_id + " (" + job_state_name(before->info.state) +
           ")";
  }
  if (job.info.spec.kind == JobKind::kMovie) {
    if (job.movie_run != 0 || job.movie_attempts == 0) return "";
    const double in = std::max(0.0, seconds(job.movie_not_before - now_()));
    return "the movie's attempt " + std::to_string(job.movie_attempts) + " failed; attempt " +
           std::to_string(job.movie_attempts + 1) + " in " + format_seconds(in);
  }
  const auto& need = job.info.spec.require;
  if (need.empty()) return "";
  for (const auto& [id, w] : workers_) {
    if (carries(w.info, job)) return "";
  }
  std::string tags;
  for (const std::string& t : need) tags += (tags.empty() ? "" : ", ") + t;
  return "waiting for a worker tagged " + tags + " (none is connected)";
}

Result<JobInfo> Scheduler::job(const std::string& job_id) const {
  const Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  return snapshot(*job);
}

bool Scheduler::job_ended(const std::string& job_id) const {
  const Job* job = find_job(job_id);
  return !job || is_terminal(job->info.state);
}

std::vector<JobInfo> Scheduler::jobs() const {
  std::vector<JobInfo> out;
  for (const std::string& id : order_) out.push_back(snapshot(jobs_.at(id)));
  return out;
}

void Scheduler::drop_leases_of(Job& job) {
  for (auto it = leases_.begin(); it != leases_.end();) {
    if (it->second.job_id == job.info.job_id) {
      forget_lease(&job, it->first, it->second);
      count_running(job, -1);
      event::LeaseEnded ended{it->first,
                              job.info.job_id,
                              frame_of(job, it->second.job_band),
                              band_of(job, it->second.job_band),
                              LeaseOutcome::kRevoked,
                              std::string("job ") + job_state_name(job.info.state),
                              false,
                              0,
                              "",
                              {}};
      account(job, ended, it->second);
      events_.push_back(std::move(ended));
      it = leases_.erase(it);
    } else {
      ++it;
    }
  }
}

void Scheduler::end_job(Job& job, JobState state, const std::string& error) {
  if (is_terminal(job.info.state)) return;
  job.info.state = state;
  track(job);
  job.info.error = error;
  job.finished = now_();
  job.movie_run = 0;  // a movie in the making is no longer wanted
  events_.push_back(event::JobStateChanged{job.info.job_id, state, error});
  drop_leases_of(job);
  // A finished job keeps its JobInfo in memory, and, when it failed or was
  // cancelled, which bands are done (for `locus retry`); the store has the
  // rest.
  if (state == JobState::kSucceeded) {
    job.bands = {};
    job.frame_bands.clear();
  }
  job.retry = {};
  job.failures.clear();
  job.worker_failures.clear();
  job.durations.clear();
  if (state == JobState::kFailed) spdlog::warn("job {} failed: {}", job.info.job_id, error);
  const BandSeconds& a = job.info.account;
  char line[160];
  std::snprintf(line, sizeof line,
                "accounting: %.3f band-seconds rendered, %.3f failed, %.3f lost; %.3f CPU seconds",
                a.done, a.failed, a.lost, job.info.stats.seconds_render_cpu);
  note(job, line);
  ++version_;
  if (state != JobState::kSucceeded) fail_dependents(job);
}

Result<JobInfo> Scheduler::cancel(const std::string& job_id, const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  if (!is_terminal(job->info.state) && !who.empty()) note(*job, "cancelled by " + who);
  end_job(*job, JobState::kCancelled, "");
  return snapshot(*job);
}

Result<JobInfo> Scheduler::set_priority(const std::string& job_id, int priority, bool preempt,
                                        const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  if (priority < kMinPriority || priority > kMaxPriority) {
    return InvalidArgument("priority: must be in [" + std::to_string(kMinPriority) + ", " +
                           std::to_string(kMaxPriority) + "], got " + std::to_string(priority));
  }
  if (is_terminal(job->info.state)) {
    return FailedPrecondition("job " + job_id + " is " + job_state_name(job->info.state) +
                              ": its priority no longer matters");
  }
  const int before = job->info.spec.priority;
  job->info.spec.priority = priority;
  job->record.spec.priority = priority;
  events_.push_back(event::PriorityChanged{job_id, priority});
  note(*job, "priority " + std::to_string(before) + " -> " + std::to_string(priority) +
                 (who.empty() ? "" : " by " + who));
  if (preempt) {
    // Every running band of a job of lower priority goes back to its queue
    // (the worker is told at its next heartbeat and abandons it).
    std::vector<std::string> lower;
    for (const auto& [id, l] : leases_) {
      const Job& other = jobs_.at(l.job_id);
      if (other.info.spec.priority < priority) lower.push_back(id);
    }
    for (const std::string& id : lower) {
      release(id, LeaseOutcome::kPreempted,
              "preempted for job " + job_id + " (priority " + std::to_string(priority) + ")");
    }
  }
  ++version_;
  return snapshot(*job);
}

Result<JobInfo> Scheduler::pause(const std::string& job_id, const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  if (job->info.state == JobState::kPaused) return snapshot(*job);
  if (is_terminal(job->info.state)) {
    return FailedPrecondition("job " + job_id + " is " + job_state_name(job->info.state) +
                              " and cannot be paused");
  }
  job->info.state = JobState::kPaused;
  events_.push_back(event::JobStateChanged{job_id, JobState::kPaused, ""});
  if (!who.empty()) note(*job, "paused by " + who);
  ++version_;
  return snapshot(*job);
}

Result<JobInfo> Scheduler::resume(const std::string& job_id, const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  if (job->info.state != JobState::kPaused) {
    return FailedPrecondition("job " + job_id + " is " + job_state_name(job->info.state) +
                              ", not paused");
  }
  const bool started = job->info.bands_done > 0 || job->running > 0 || !job->failures.empty();
  job->info.state = started ? JobState::kRunning : JobState::kQueued;
  job->waiting_since = now_();
  events_.push_back(event::JobStateChanged{job_id, job->info.state, ""});
  if (!who.empty()) note(*job, "resumed by " + who);
  ++version_;
  return snapshot(*job);
}

void Scheduler::account(Job& job, event::LeaseEnded& ended, const Lease& lease) {
  ended.seconds = seconds(now_() - lease.granted);
  ended.owner = job.info.spec.owner;
  (is_charged(ended.outcome) ? job.info.account.failed : job.info.account.lost) += ended.seconds;
  ended.job_account = job.info.account;
}

void Scheduler::note(const Job& job, std::string text) {
  events_.push_back(event::JobNote{job.info.job_id, std::move(text)});
}

void Scheduler::track(Job& job) {
  if (is_terminal(job.info.state)) {
    live_.erase(job.record.seq);
  } else {
    live_[job.record.seq] = &job;
  }
}

void Scheduler::forget_lease(Job* job, const std::string& lease_id, const Lease& lease) {
  auto w = workers_.find(lease.worker_id);
  if (w != workers_.end()) w->second.leases.erase(lease_id);
  if (job) job->solo.erase({lease.granted, lease_id});
}

void Scheduler::count_running(Job& job, int delta) {
  job.running += delta;
  user_running_[job.info.spec.owner] += delta;
}

bool Scheduler::frame_written(const std::string& job_id, int frame, const Status& status) {
  Job* job = find_job(job_id);
  if (!job || is_terminal(job->info.state)) return false;
  // Kept in order (a requeued frame comes back among the others).
  auto& written = job->info.frames_written;
  const auto at = std::lower_bound(written.begin(), written.end(), frame);
  if (at != written.end() && *at == frame) return false;
  if (!status.ok()) {
    end_job(*job, JobState::kFailed, "frame " + std::to_string(frame) + ": " + status.message());
    return false;
  }
  ++job->info.frames_done;
  written.insert(at, frame);
  events_.push_back(event::FrameWritten{job_id, frame, frame_path(job->info.spec.output, frame)});
  ++version_;
  if (job->info.frames_done == job->info.spec.frames()) {
    end_job(*job, JobState::kSucceeded, "");
    spdlog::info("job {} succeeded in {:.3f} s ({} frames, {} bands)", job_id,
                 seconds(job->finished - job->submitted), job->info.spec.frames(),
                 job->info.spec.bands_total());
  }
  return true;
}

}  // namespace locus::farm
