// The coordinator's scheduling logic as a plain, single-threaded class:
// jobs expand into frames x bands tasks; each task is leased to one worker
// at a time (lease id + deadline); leases lapse when not renewed, and their
// bands go back to the queue; results under a stale lease are dropped;
// accepted bands are stitched into their frame. No network, no threads, no
// files: the caller (Coordinator) locks, writes frames, and drives time
// through the injected clock, which is how the tests drive it too.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "server/farm_types.h"

namespace locus::farm {

struct SchedulerOptions {
  Millis lease{5000};           // a lease lapses this long after its last renewal
  Millis worker_timeout{5000};  // a worker silent this long is gone, with its leases
  int max_attempts = 3;         // leases per band (lapsed or failed) before the job fails
};

// The answer to a returned band.
struct CompleteOutcome {
  bool accepted = false;
  std::string reason;               // why it was dropped
  std::optional<FrameImage> frame;  // the band completed this frame: write it
};

class Scheduler {
 public:
  Scheduler(SchedulerOptions options, NowFn now);

  // ---- jobs ----
  // `spec` is validated by the caller; returns the new job's id.
  std::string add_job(JobSpec spec);
  Result<JobInfo> job(const std::string& job_id) const;
  std::vector<JobInfo> jobs() const;
  Result<JobInfo> cancel(const std::string& job_id);
  // The caller wrote (or failed to write) a frame handed out by complete_band.
  void frame_written(const std::string& job_id, int frame, const Status& status);

  // ---- workers ----
  std::string add_worker(const std::string& name, int threads);
  // Marks the worker alive; NotFound when it is unknown (or was dropped).
  Status touch(const std::string& worker_id);
  std::vector<WorkerInfo> workers() const;
  size_t worker_count() const { return workers_.size(); }

  // Leases the next band to the worker, or nothing when no band waits.
  Result<std::optional<BandTask>> next_task(const std::string& worker_id);
  // Renews the worker's leases; returns those it must drop (re-leased,
  // lapsed, cancelled).
  Result<std::vector<std::string>> heartbeat(const std::string& worker_id,
                                             const std::vector<std::string>& lease_ids);
  // A band's pixels or error. InvalidArgument for malformed pixels (the
  // band goes back to the queue); a stale lease is not an error but
  // `accepted == false`.
  Result<CompleteOutcome> complete_band(BandOutput output);

  // Lapses leases past their deadline and drops workers silent past
  // worker_timeout; their bands go back to the queue.
  void expire();

  // Content hashes of the scenes that unfinished jobs still need.
  std::set<std::string> scenes_in_use() const;
  // Jobs queued or running (the --max-jobs limit).
  size_t unfinished_jobs() const;

  // Bumped by every change a watcher may want to see.
  uint64_t version() const { return version_; }
  bool has_queued_bands() const;

 private:
  enum class TaskState { kQueued, kLeased, kDone };
  struct Task {
    TaskState state = TaskState::kQueued;
    int attempts = 0;
    std::string lease_id;
    std::string last_error;
  };
  struct PartialFrame {
    Image image;
    int bands_done = 0;
  };
  struct Job {
    JobInfo info;
    TimePoint submitted;
    TimePoint finished;
    std::vector<Task> tasks;  // frame-major: (frame - first) * bands + band
    std::deque<int> queue;    // task indices waiting for a worker
    std::map<int, PartialFrame> partial;
    std::set<int> stitched;  // frames handed out for writing
  };
  struct Lease {
    std::string job_id;
    int task = 0;
    std::string worker_id;
    TimePoint deadline;
  };
  struct Worker {
    WorkerInfo info;
    TimePoint last_seen;
    std::set<std::string> leases;
  };

  Job* find_job(const std::string& id);
  const Job* find_job(const std::string& id) const;
  JobInfo snapshot(const Job& job) const;
  // Ends a lease; its band is queued again (first, to finish frames early)
  // and charged an attempt, unless `charge` is false.
  void release(const std::string& lease_id, const std::string& why, bool charge);
  void fail_job(Job& job, const std::string& error);
  void drop_leases_of(Job& job);
  BandTask make_task(const Job& job, int task, const Lease& lease) const;

  SchedulerOptions options_;
  NowFn now_;
  std::vector<std::string> order_;  // job ids, oldest first: dispatch is FIFO by job
  std::map<std::string, Job> jobs_;
  std::map<std::string, Lease> leases_;
  std::map<std::string, Worker> workers_;
  uint64_t next_job_ = 1;
  uint64_t next_worker_ = 1;
  uint64_t next_lease_ = 1;
  std::string lease_prefix_;
  uint64_t version_ = 0;
};

}  // namespace locus::farm
