// Scheduler's movie jobs (JobKind::kMovie, docs/farm.md "Movies"): a job
// without bands that waits for its render job like any `--after` job and
// that the coordinator, not a worker, makes once the frames are written.
// Here: which movie may run, and what its outcome does to the job (success,
// a retry after back-off, failure after the attempt limit). The ffmpeg run
// itself is common/farm/movie.h's, driven by Coordinator::movie_loop.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/scheduler.h"

namespace locus::farm {

std::optional<Scheduler::MovieTask> Scheduler::next_movie() {
  const TimePoint now = now_();
  // The unfinished movie jobs, oldest first (end_job below takes jobs out
  // of live_, so the walk goes over a copy).
  std::vector<Job*> movies;
  for (const auto& [seq, job] : live_) {
    if (job->info.spec.kind == JobKind::kMovie) movies.push_back(job);
  }
  for (Job* live : movies) {
    Job& job = *live;
    const std::string& id = job.info.job_id;
    const JobState st = job.info.state;
    if (job.info.spec.kind != JobKind::kMovie || is_terminal(st) || st == JobState::kPaused)
      continue;
    if (job.movie_run != 0 || now < job.movie_not_before || waiting_for(job)) continue;
    const JobSpec& spec = job.info.spec;
    const Job* source = spec.after.empty() ? nullptr : find_job(spec.after.front());
    if (!source) {
      end_job(job, JobState::kFailed,
              "its render job " + (spec.after.empty() ? std::string("?") : spec.after.front()) +
                  " was deleted before the movie was made");
      continue;
    }
    job.movie_run = next_movie_run_++;
    ++job.movie_attempts;
    if (st == JobState::kQueued) {
      job.info.state = JobState::kRunning;
      events_.push_back(event::JobStateChanged{id, JobState::kRunning, ""});
    }
    note(job, "making the movie " + spec.output + " of frames " +
                  std::to_string(source->info.spec.frame_first) + "-" +
                  std::to_string(source->info.spec.frame_last) + " of job " +
                  source->info.job_id + " at " + std::to_string(spec.fps) + " fps (attempt " +
                  std::to_string(job.movie_attempts) + ")");
    ++version_;
    return MovieTask{id, spec, source->info.spec, source->info.job_id, job.movie_run,
                     job.movie_attempts};
  }
  return std::nullopt;
}

bool Scheduler::movie_wanted(const std::string& job_id, uint64_t run) const {
  const Job* job = find_job(job_id);
  return job && run != 0 && job->movie_run == run && !is_terminal(job->info.state);
}

bool Scheduler::movie_done(const std::string& job_id, uint64_t run, const Status& status) {
  if (!movie_wanted(job_id, run)) return false;
  Job& job = *find_job(job_id);
  job.movie_run = 0;
  if (status.ok()) return frame_written(job_id, 1, status);  // its one output: the job succeeds
  const int limit = std::max(1, options_.max_attempts);
  if (job.movie_attempts >= limit) {
    end_job(job, JobState::kFailed,
            "movie: " + status.message() + " (after " + std::to_string(job.movie_attempts) +
                " attempt" + (job.movie_attempts == 1 ? "" : "s") + ")");
    return true;
  }
  // Back-off: 1 s after the first failure, then twice as long each time.
  const Millis wait(1000LL << std::min(job.movie_attempts - 1, 10));
  job.movie_not_before = now_() + wait;
  note(job, "the movie's attempt " + std::to_string(job.movie_attempts) +
                " failed: " + status.message() + "; again in " +
                std::to_string(wait.count() / 1000) + " s");
  spdlog::warn("job {}: the movie's attempt {} failed: {}", job_id, job.movie_attempts,
               status.message());
  ++version_;
  return true;
}

std::optional<TimePoint> Scheduler::next_movie_time() const {
  std::optional<TimePoint> next;
  for (const auto& [seq, job] : live_) {
    if (job->info.spec.kind != JobKind::kMovie) continue;
    if (job->movie_run != 0 || job->movie_attempts == 0) continue;
    if (!next || job->movie_not_before < *next) next = job->movie_not_before;
  }
  return next;
}

}  // namespace locus::farm
