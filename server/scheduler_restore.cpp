// Scheduler::restore: after a restart, the jobs of the previous run rebuilt
// from what the job store recovered (server/store.h): which bands are done,
// which failed where, which wait, and which frames are complete but not yet
// written. Its own file because nothing else in the Scheduler reads the
// store's records; the steps below run once per unfinished job.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/scene/animation.h"
#include "server/scheduler.h"

namespace locus::farm {
namespace {

// A store row names a band of this job (a damaged row may not).
bool in_job(const JobSpec& s, int frame, int band) {
  return frame >= s.frame_first && frame <= s.frame_last && band >= 0 && band < s.bands;
}

}  // namespace

std::vector<FrameReady> Scheduler::restore(const RecoveredState& state) {
  std::vector<FrameReady> ready;
  const TimePoint now = now_();
  next_worker_ = std::max<uint64_t>(next_worker_, state.next_worker);
  disabled_.insert(state.disabled_workers.begin(), state.disabled_workers.end());
  for (const RecoveredJob& r : state.jobs) {
    Job job = recovered_job(r, now);
    if (!is_terminal(r.state)) {
      job.bands.resize(job.info.spec.bands_total());
      mark_done_bands(job, r);
      charge_failures(job, r);
      queue_unfinished(job);
      for (FrameReady& f : take_complete_frames(job)) ready.push_back(std::move(f));
      const JobInfo& info = job.info;
      spdlog::info("job {} resumed: {}/{} bands done, {}/{} frames written", info.job_id,
                   info.bands_done, info.spec.bands_total(), info.frames_done, info.spec.frames());
    } else if (r.state != JobState::kSucceeded) {
      // Which bands are done, for `locus retry` (end_job keeps as much).
      job.bands.resize(job.info.spec.bands_total());
      mark_done_bands(job, r);
    }
    next_job_ = std::max<uint64_t>(next_job_, static_cast<uint64_t>(r.record.seq) + 1);
    if (!r.record.request_id.empty()) requests_[r.record.request_id] = job.info.job_id;
    if (job.info.spec.kind == JobKind::kMovie && !job.info.spec.after.empty())
      movies_[job.info.spec.after.front()] = job.info.job_id;
    order_.push_back(job.info.job_id);
    const std::string id = job.info.job_id;
    track(jobs_.emplace(id, std::move(job)).first->second);
  }
  ++version_;
  return ready;
}

Scheduler::Job Scheduler::recovered_job(const RecoveredJob& r, TimePoint now) {
  Job job;
  job.record = r.record;
  JobInfo& info = job.info;
  info.job_id = r.record.job_id;
  info.spec = r.record.spec;
  info.state = r.state;
  info.error = r.error;
  info.stats = r.stats;
  info.account = r.account;
  info.results_discarded = r.results_discarded;
  info.speculative_leases = r.speculative_leases;
  info.frames_written = r.frames_written;
  std::sort(info.frames_written.begin(), info.frames_written.end());
  info.frames_done = static_cast<int>(info.frames_written.size());
  info.bands_done = r.bands_done;
  // The clock does not survive the restart: the job's age does.
  job.submitted = now - std::chrono::duration_cast<SteadyClock::duration>(
                            std::chrono::duration<double>(std::max(0.0, r.seconds_elapsed)));
  job.finished = now;
  job.waiting_since = now;
  return job;
}

void Scheduler::mark_done_bands(Job& job, const RecoveredJob& r) {
  const JobSpec& s = job.info.spec;
  for (int f : job.info.frames_written) {
    if (f < s.frame_first || f > s.frame_last) continue;
    for (int b = 0; b < s.bands; ++b) job.bands[job_band_of(s, f, b)].phase = BandPhase::kDone;
  }
  for (const RecoveredJob::BandRef& b : r.done_bands) {
    if (!in_job(s, b.frame, b.band)) continue;
    BandState& state = job.bands[job_band_of(s, b.frame, b.band)];
    if (state.phase == BandPhase::kDone) continue;  // its frame is written
    state.phase = BandPhase::kDone;
    ++job.frame_bands[b.frame];
  }
}

void Scheduler::charge_failures(Job& job, const RecoveredJob& r) const {
  const JobSpec& s = job.info.spec;
  for (const RecoveredJob::Failure& f : r.failures) {
    if (!in_job(s, f.frame, f.band)) continue;
    const int i = static_cast<int>(job_band_of(s, f.frame, f.band));
    BandState& state = job.bands[i];
    if (state.failures < 255) ++state.failures;
    job.failures[i].workers.insert(f.worker_name);
    job.failures[i].last_error = f.error;
    ++job.worker_failures[f.worker_name];
  }
  for (const auto& [name, n] : job.worker_failures) {
    if (options_.quarantine_after > 0 && n >= options_.quarantine_after)
      job.info.quarantined.push_back(name);
  }
}

void Scheduler::queue_unfinished(Job& job) {
  // In the order bands are first leased (fresh_band): those up to the last
  // one done or failed go back to the queue (served first); those after it
  // were never leased, or only under leases the restart voided, and are
  // fresh.
  int64_t done = 0;
  int last_touched = -1;
  const int n = static_cast<int>(job.bands.size());
  for (int k = 0; k < n; ++k) {
    const int i = fresh_band(job, k);
    if (job.bands[i].phase == BandPhase::kDone) {
      ++done;
      last_touched = k;
    } else if (job.failures.count(i)) {
      last_touched = k;
    }
  }
  job.info.bands_done = done;
  job.next_fresh = last_touched + 1;
  for (int k = 0; k < job.next_fresh; ++k) {
    const int i = fresh_band(job, k);
    if (job.bands[i].phase != BandPhase::kDone) job.retry.push_back(i);
  }
}

std::vector<FrameReady> Scheduler::take_complete_frames(Job& job) {
  const JobSpec& s = job.info.spec;
  std::vector<FrameReady> ready;
  for (auto it = job.frame_bands.begin(); it != job.frame_bands.end();) {
    if (it->second == s.bands) {
      ready.push_back(frame_ready(job.info.job_id, s, it->first));
      it = job.frame_bands.erase(it);
    } else {
      ++it;
    }
  }
  return ready;
}

}  // namespace locus::farm
