// Scheduler::retry and Scheduler::requeue: a job back in the queue
// (`locus retry`, `locus requeue`), rebuilt from its bands' phases. Its own
// file, like the restart's: nothing else in the Scheduler reopens a job.
#include <algorithm>
#include <set>

#include "server/scheduler.h"

namespace locus::farm {

Status Scheduler::check_predecessors(const Job& job) const {
  for (const std::string& id : job.info.spec.after) {
    const Job* before = find_job(id);  // a deleted one no longer holds it back
    if (!before) continue;
    const JobState st = before->info.state;
    if (st == JobState::kFailed || st == JobState::kCancelled) {
      return FailedPrecondition("job " + job.info.job_id + " waits for job " + id + ", which " +
                                job_state_name(st) + "; retry " + id + " first");
    }
  }
  return Status::Ok();
}

std::vector<FrameReady> Scheduler::reopen_ended(Job& job, const std::vector<int>& requeued,
                                                const std::string& note_text) {
  const std::set<int> written(job.info.frames_written.begin(), job.info.frames_written.end());
  job.retry.clear();
  job.frame_bands.clear();
  job.failures.clear();
  job.worker_failures.clear();
  job.info.quarantined.clear();
  job.durations.clear();
  job.movie_run = 0;
  job.movie_attempts = 0;
  job.movie_not_before = {};
  for (size_t i = 0; i < job.bands.size(); ++i) {
    BandState& b = job.bands[i];
    b.failures = 0;
    b.leases = 0;  // the leases were revoked when the job ended
    b.speculated = 0;
    if (b.phase == BandPhase::kLeased) b.phase = BandPhase::kQueued;
    const int frame = frame_of(job, static_cast<int>(i));
    if (b.phase == BandPhase::kDone && !written.count(frame)) ++job.frame_bands[frame];
  }
  queue_unfinished(job);
  job.info.state = JobState::kQueued;
  track(job);
  job.info.error.clear();
  job.waiting_since = now_();
  events_.push_back(event::JobReopened{job.info.job_id, JobState::kQueued, requeued, true});
  note(job, note_text);
  ++version_;
  return take_complete_frames(job);
}

Result<Scheduler::Reopened> Scheduler::retry(const std::string& job_id, const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  const JobState st = job->info.state;
  if (st != JobState::kFailed && st != JobState::kCancelled) {
    return FailedPrecondition(
        "job " + job_id + " is " + job_state_name(st) + "; only a failed or cancelled job is " +
        "retried" + (st == JobState::kSucceeded ? " (`locus requeue` renders frames again)" : ""));
  }
  if (Status s = check_predecessors(*job); !s.ok()) return s;
  const int64_t missing =
      static_cast<int64_t>(job->bands.size()) -
      std::count_if(job->bands.begin(), job->bands.end(),
                    [](const BandState& b) { return b.phase == BandPhase::kDone; });
  Reopened out;
  out.ready = reopen_ended(*job, {},
                           "retried" + (who.empty() ? std::string() : " by " + who) + ": " +
                               std::to_string(missing) +
                               " bands back in the queue with fresh attempts");
  out.info = snapshot(*job);
  return out;
}

Result<Scheduler::Reopened> Scheduler::requeue(const std::string& job_id,
                                               std::optional<int> first_frame,
                                               std::optional<int> last_frame,
                                               const std::string& who) {
  Job* job = find_job(job_id);
  if (!job) return NotFound("job '" + job_id + "' is unknown; `locus status` lists the jobs");
  const JobSpec& s = job->info.spec;
  const int first = first_frame.value_or(s.frame_first);
  const int last = last_frame.value_or(s.frame_last);
  if (first > last || first < s.frame_first || last > s.frame_last) {
    return InvalidArgument("frames " + std::to_string(first) + "-" + std::to_string(last) +
                           ": job " + job_id + " has frames " + std::to_string(s.frame_first) +
                           "-" + std::to_string(s.frame_last));
  }
  const JobState st = job->info.state;
  const bool ended = is_terminal(st);
  if (ended) {
    if (Status e = check_predecessors(*job); !e.ok()) return e;
  }
  std::vector<int> frames;
  for (int f : job->info.frames_written) {
    if (f >= first && f <= last) frames.push_back(f);
  }
  std::sort(frames.begin(), frames.end());
  if (frames.empty() && !ended) {
    return FailedPrecondition("no frame in " + std::to_string(first) + "-" +
                              std::to_string(last) + " of job " + job_id +
                              " is written yet: they are still to render");
  }
  // A job that succeeded kept no band states: every band was done.
  if (job->bands.empty()) {
    job->bands.assign(static_cast<size_t>(s.bands_total()), BandState{BandPhase::kDone, 0, 0, 0});
  }
  const std::set<int> again(frames.begin(), frames.end());
  auto& written = job->info.frames_written;
  written.erase(std::remove_if(written.begin(), written.end(),
                               [&](int f) { return again.count(f) > 0; }),
                written.end());
  job->info.frames_done = static_cast<int>(written.size());
  for (int f : frames) {
    for (int b = 0; b < s.bands; ++b) {
      const int i = static_cast<int>(job_band_of(s, f, b));
      job->bands[i].phase = BandPhase::kQueued;
      --job->info.bands_done;
      if (!ended) job->retry.push_back(i);
    }
  }
  const std::string text =
      "frames " + std::to_string(first) + "-" + std::to_string(last) + " requeued" +
      (who.empty() ? std::string() : " by " + who) + ": " + std::to_string(frames.size()) +
      " written frames render again";
  Reopened out;
  if (ended) {
    out.ready = reopen_ended(*job, frames, text);
  } else {
    events_.push_back(event::JobReopened{job_id, st, frames, false});
    note(*job, text);
    ++version_;
  }
  out.info = snapshot(*job);
  return out;
}

}  // namespace locus::farm
