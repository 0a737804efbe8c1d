// Coordinator's movie jobs (docs/farm.md "Movies"): the thread that makes
// them with ffmpeg outside the lock, and the movie job recorded with a
// render job that asks for one. Which movie may run, and what its outcome
// does, is the Scheduler's (server/scheduler_movie.cpp).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>

#include "common/farm/movie.h"
#include "server/coordinator.h"

namespace locus::farm {
namespace fs = std::filesystem;

void Coordinator::movie_loop() {
  std::unique_lock lk(mu_);
  while (!stopping_) {
    std::optional<Scheduler::MovieTask> task;
    if (!draining_) task = scheduler_.next_movie();
    if (!task) {
      // Woken by every change (a render job that succeeds among them); a
      // movie backing off is looked at again when its time comes.
      auto wait = Millis(1000);
      if (auto at = scheduler_.next_movie_time()) {
        wait = std::clamp(std::chrono::duration_cast<Millis>(*at - options_.now()), Millis(10),
                          wait);
      }
      changed_.wait_for(lk, wait);
      continue;
    }
    persist();
    changed_.notify_all();
    const std::string dir = job_dir(task->job_id);
    MovieInput in;
    in.frames_dir = job_dir(task->source_id);
    in.pattern = task->source.output;
    in.first = task->source.frame_first;
    in.last = task->source.frame_last;
    in.fps = task->movie.fps;
    in.out_path = (fs::path(dir) / task->movie.output).string();
    lk.unlock();
    std::error_code ec;
    fs::create_directories(dir, ec);
    // Stopped when the job no longer wants it (cancelled, deleted,
    // reopened) or the coordinator stops: a stop leaves the job running in
    // the store, and the next start makes the movie again.
    auto made = assemble_movie(in, [&] {
      std::lock_guard g(mu_);
      return stopping_ || !scheduler_.movie_wanted(task->job_id, task->run);
    });
    lk.lock();
    if (stopping_ && !made.ok()) break;
    const Status st = made.ok() ? Status::Ok() : made.status();
    if (made.ok()) {
      spdlog::info("job {}: movie {} written ({} bytes, frames {}-{} of job {})", task->job_id,
                   in.out_path, *made, in.first, in.last, task->source_id);
    }
    scheduler_.movie_done(task->job_id, task->run, st);
    persist();
    changed_.notify_all();
  }
}

JobSpec Coordinator::movie_spec(const JobSpec& render, const std::string& render_id) const {
  JobSpec m;
  m.kind = JobKind::kMovie;
  m.scene_hash = render.scene_hash;
  m.scene_name = render.scene_name;
  m.width = render.width;
  m.height = render.height;
  m.frame_first = m.frame_last = 1;  // one output: the movie
  m.bands = 0;
  m.output = render.movie;
  m.fps = render.fps;
  m.priority = render.priority;
  m.owner = render.owner;
  m.after = {render_id};
  // Told when all is done: the movie's end is the job's end (a render job
  // that fails fails its movie job too, with the reason).
  m.notify_url = render.notify_url;
  return m;
}

}  // namespace locus::farm
