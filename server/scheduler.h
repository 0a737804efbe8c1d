// The coordinator's scheduling logic as a plain, single-threaded class:
// a job's frames are cut into bands; each band is leased to a worker
// (lease id + deadline), and at most once more, speculatively, when it runs
// far longer than its peers; leases lapse when not renewed and their bands
// go back to the queue; results under a stale lease are dropped; failures
// are charged to the band (attempt limit) and to the worker (quarantine).
// No network, no threads, no files: the caller (Coordinator) locks, keeps
// band files and frames on disk, drives time through the injected clock and
// hands every durable change, taken with take_events(), to the JobStore.
// The tests drive it the same way.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/farm/types.h"
#include "server/journal.h"

namespace locus::farm {

struct SchedulerOptions {
  Millis lease{5000};           // a lease lapses this long after its last renewal
  Millis worker_timeout{5000};  // a worker silent this long is gone, with its leases
  int max_attempts = 3;         // failed leases per band before the job fails
  int quarantine_after = 2;     // failures of one worker in a job before it gets no more of it
  // A band leased longer than speculate_factor x the median time of its
  // job's finished bands (and at least speculate_min) gets a second lease
  // when a worker has nothing else to do; 0 turns speculation off.
  double speculate_factor = 3.0;
  Millis speculate_min{1000};
  // A band leased longer than this is taken back (a hung render whose
  // worker still heartbeats); a job's own band_timeout overrides it; 0: none.
  Millis band_timeout{0};
  // Ageing: a job with bands waiting gains one priority point for each
  // `ageing` since it last got a lease, so that no job starves; 0: none.
  Millis ageing{60000};
  // Most bands one user's jobs may run at once; 0: no cap.
  int user_max_running = 0;
  // EXR jobs' bands as exr+zip where the worker offers it and the band
  // holds a block: the workers compress the frame's blocks, and the
  // coordinator writes them as they come; false (--no-exr-zip):
  // float32+zstd, 2.9 times fewer bytes on the wire, and the coordinator
  // compresses each frame (docs/farm.md "Frames").
  bool exr_zip = true;
};

// The answer to a returned band.
struct CompleteOutcome {
  bool accepted = false;
  std::string reason;               // why it was dropped
  std::optional<FrameReady> frame;  // the band completed this frame: write it
};

// Where an acceptable result goes: checked before its pixels are written.
struct BandTarget {
  std::string job_id;
  int frame = 0;
  int band = 0;
  int width = 0;
  int y0 = 0;
  int y1 = 0;
};

class Scheduler {
 public:
  Scheduler(SchedulerOptions options, NowFn now);

  // ---- restart ----
  // Rebuilds the jobs a store remembered (before any other call). Returns
  // the frames whose bands are all done but which were not yet written.
  std::vector<FrameReady> restore(const RecoveredState& state);

  // ---- jobs ----
  // `spec` is validated by the caller; returns the new job's id.
  std::string add_job(JobSpec spec, const std::string& request_id = "",
                      const std::string& fingerprint = "");
  // Undoes add_job when its record could not be stored, and removes a job
  // deleted from the store (`locus delete`, retention).
  void forget_job(const std::string& job_id);
  // The job an earlier submission with this request id created, if any.
  std::optional<JobRecord> job_for_request(const std::string& request_id) const;
  Result<JobInfo> job(const std::string& job_id) const;
  // Whether the job has ended (or is unknown), without a snapshot: cheap
  // enough for a wait's predicate.
  bool job_ended(const std::string& job_id) const;
  std::vector<JobInfo> jobs() const;
  // The operators' actions; `who` names the caller in the job's history.
  Result<JobInfo> cancel(const std::string& job_id, const std::string& who = "");
  // Takes effect at the next lease. `preempt`: running bands of jobs of
  // lower priority are handed back at once (not charged; they render again).
  Result<JobInfo> set_priority(const std::string& job_id, int priority, bool preempt,
                               const std::string& who = "");
  // No new leases while paused; bands in flight finish and are kept.
  Result<JobInfo> pause(const std::string& job_id, const std::string& who = "");
  Result<JobInfo> resume(const std::string& job_id, const std::string& who = "");
  // A job that goes back to the queue (`locus retry`, `locus requeue`).
  struct Reopened {
    JobInfo info;
    // Frames whose bands are all done but which were never written (the
    // job ended first): the caller writes them now.
    std::vector<FrameReady> ready;
  };
  // `locus retry`: a failed or cancelled job goes back to the queue; its
  // bands not done get fresh attempts (their failures and the job's
  // quarantines are forgotten). FailedPrecondition for any other state, or
  // while a job it waits for has failed or was cancelled.
  Result<Reopened> retry(const std::string& job_id, const std::string& who = "");
  // `locus requeue`: the written frames in [first, last] render again (the
  // caller replaces each file only when its new frame is complete). A job
  // that succeeded goes back to the queue; one that failed or was cancelled
  // is retried as well. InvalidArgument for frames outside the job's; an
  // absent bound is the job's first or last frame.
  Result<Reopened> requeue(const std::string& job_id, std::optional<int> first,
                           std::optional<int> last, const std::string& who = "");
  // The caller wrote (or failed to write) a frame handed out as ready.
  // False when the job no longer expects it (it ended, or has it already):
  // the frame's band files must then stay, for a retry to stitch it again.
  bool frame_written(const std::string& job_id, int frame, const Status& status);

  // ---- movies (JobKind::kMovie: no bands; the coordinator makes them) ----
  struct MovieTask {
    std::string job_id;  // the movie job
    JobSpec movie;       // output: the movie's file name; fps
    JobSpec source;      // the render job's (its frames' pattern and range)
    std::string source_id;
    uint64_t run = 0;  // this attempt, for movie_done()
    int attempt = 1;
  };
  // The next movie job that may run now: its render job succeeded, it is
  // neither paused nor backing off after a failure, and nobody makes it
  // yet. It is running from here on. Nothing when none may.
  std::optional<MovieTask> next_movie();
  // How the attempt `run` of a movie task ended. OK: the movie is written
  // and the job succeeds. An error: the job tries again after 1 s, 2 s,
  // 4 s ... up to max_attempts attempts, then fails with it. False when the
  // job no longer expects this attempt (it ended, was reopened or deleted).
  bool movie_done(const std::string& job_id, uint64_t run, const Status& status);
  // Whether the attempt `run` of the movie job still counts (the
  // coordinator stops ffmpeg when it does not).
  bool movie_wanted(const std::string& job_id, uint64_t run) const;
  // The earliest moment a movie job backing off may run again, if any.
  std::optional<TimePoint> next_movie_time() const;

  // ---- workers ----
  // `tags` (the worker's pools) are checked by the caller.
  std::string add_worker(const std::string& name, int threads,
                         const std::vector<std::string>& tags = {}, EncodingOffers offers = {});
  // Dependencies of a new job: OK when every id names a job that has not
  // failed or been cancelled; InvalidArgument naming the id otherwise.
  Status check_after(const std::vector<std::string>& after) const;
  // Marks the worker alive; NotFound when it is unknown (or was dropped).
  Status touch(const std::string& worker_id);
  std::vector<WorkerInfo> workers() const;
  // `locus drain`: the connected worker (by id or name) finishes its band,
  // gets no more and is told to exit. NotFound for an unknown worker.
  Result<WorkerInfo> drain_worker(const std::string& worker);
  // `locus disable` / `enable`: the worker of that id or name gets no band
  // of any job (it stays connected) until enabled, across its reconnects
  // and a restart. NotFound when no connected or disabled worker has it.
  Result<std::string> set_disabled(const std::string& worker, bool disabled);
  // Whether the worker was asked to drain (its heartbeats and polls say so).
  bool draining(const std::string& worker_id) const;
  size_t worker_count() const { return workers_.size(); }

  // Leases the next band to the worker, or nothing when no band waits.
  Result<std::optional<BandLease>> next_band(const std::string& worker_id);
  // Renews the worker's leases; returns those it must drop (re-leased,
  // lapsed, cancelled, won by another worker).
  Result<std::vector<std::string>> heartbeat(const std::string& worker_id,
                                             const std::vector<std::string>& lease_ids);
  // Where the pixels of this result go, if it would be accepted now (a live
  // lease of the sender, pixels of the right size, no error). Nothing:
  // complete_band() will refuse it or record the failure.
  std::optional<BandTarget> result_target(const BandOutput& output) const;
  // A band's pixels (already in its band file), its error, or its hand-back.
  // InvalidArgument for malformed pixels (the band goes back to the queue);
  // a stale lease is not an error but `accepted == false`.
  Result<CompleteOutcome> complete_band(const BandOutput& output);

  // Lapses leases past their deadline and drops workers silent past
  // worker_timeout; their bands go back to the queue.
  void expire();

  // Content hashes of the scenes that unfinished jobs still need.
  std::set<std::string> scenes_in_use() const;
  // ... and of every job's, finished or not (until it is deleted): a retry
  // or a requeue needs its scene again.
  std::set<std::string> scenes_kept() const;
  // Jobs queued or running (the --max-jobs limit).
  size_t unfinished_jobs() const;
  // Bands and jobs by state, workers: the metrics' gauges.
  FarmCounts counts() const;

  // Every durable change since the last call, oldest first.
  std::vector<Event> take_events() { return std::exchange(events_, {}); }

  // Bumped by every change a watcher may want to see.
  uint64_t version() const { return version_; }
  bool has_queued_bands() const;

 private:
  enum class BandPhase : uint8_t { kQueued, kLeased, kDone };
  // One band of a job. Compact: a job may have a million bands.
  struct BandState {
    BandPhase phase = BandPhase::kQueued;
    uint8_t failures = 0;  // charged attempts
    uint8_t leases = 0;    // live leases (2 while speculating)
    uint8_t speculated = 0;
  };
  struct Failures {
    std::set<std::string> workers;  // names of the workers it failed on
    std::string last_error;
  };
  struct Job {
    JobInfo info;
    JobRecord record;
    TimePoint submitted;
    TimePoint finished;
    // Every band of the job, frame-major: the band's index in the job (its
    // "job band", as the members below count) is (frame - first) * spec.bands
    // + band, its index in the frame.
    std::vector<BandState> bands;
    int next_fresh = 0;                          // job bands from here on were never leased
    std::deque<int> retry;                       // job bands back in the queue, served first
    std::map<int, int> frame_bands;              // bands done of the frames in progress
    std::map<int, Failures> failures;            // by job band
    std::map<std::string, int> worker_failures;  // by worker name
    std::deque<double> durations;                // seconds of the last accepted bands
    int running = 0;                             // live leases
    // The leases that could get a speculative copy (not speculative, their
    // band never speculated), oldest grant first: speculation looks at the
    // oldest few, not at every lease of the farm.
    std::set<std::pair<TimePoint, std::string>> solo;
    TimePoint waiting_since;                     // its last lease, submission or resume (ageing)
    // Movie jobs: an attempt in hand (its run number; 0: none), the
    // attempts so far, and when the next may start after a failure.
    uint64_t movie_run = 0;
    int movie_attempts = 0;
    TimePoint movie_not_before;
  };
  // The coordinator's record of a lease; the worker gets it as a BandLease
  // (make_lease).
  struct Lease {
    std::string job_id;
    int job_band = 0;
    std::string worker_id;
    std::string worker_name;
    TimePoint granted;
    TimePoint deadline;
    bool speculative = false;
  };
  struct Worker {
    WorkerInfo info;
    TimePoint last_seen;
    std::set<std::string> leases;
  };

  // restore()'s steps, for one job (server/scheduler_restore.cpp).
  static Job recovered_job(const RecoveredJob& r, TimePoint now);
  static void mark_done_bands(Job& job, const RecoveredJob& r);
  void charge_failures(Job& job, const RecoveredJob& r) const;
  static void queue_unfinished(Job& job);
  // The frames whose bands are all done, taken out of frame_bands.
  static std::vector<FrameReady> take_complete_frames(Job& job);
  // A finished job back in the queue, rebuilt from its bands' phases: the
  // bands not done queued with fresh attempts (retry and requeue).
  std::vector<FrameReady> reopen_ended(Job& job, const std::vector<int>& requeued,
                                       const std::string& note_text);
  // OK unless a job this one waits for failed or was cancelled.
  Status check_predecessors(const Job& job) const;

  Job* find_job(const std::string& id);
  const Job* find_job(const std::string& id) const;
  JobInfo snapshot(const Job& job) const;
  // JobInfo::waiting: a job it waits for, or the tags no connected worker
  // carries; empty when it runs, may run, is paused or is over.
  std::string waiting_reason(const Job& job) const;
  bool queued(const Job& job) const {
    return !job.retry.empty() || job.next_fresh < static_cast<int>(job.bands.size());
  }
  bool quarantined(const Job& job, const std::string& worker_name) const;
  // Whether a registered worker other than `worker_name` may take bands of
  // the job and has not failed on `job_band` (-1: any band).
  bool another_worker_for(const Job& job, int job_band, const std::string& worker_name) const;
  // The job band the worker should take next in this job, or -1.
  int pick_band(Job& job, const std::string& worker_name);
  // The job band leased `position`-th among those never leased before
  // (JobSpec::frame_order), for position < bands.size().
  static int fresh_band(const Job& job, int position);
  // The best job that may lease a band to this worker now, other than
  // those `passed`: priority (with ageing), then the fewest running bands
  // of the job's owner, then of the job, then the oldest; null: none.
  Job* best_job(const WorkerInfo& worker, const std::vector<const Job*>& passed);
  double effective_priority(const Job& job, TimePoint now) const;
  // A lease starts or ends: the running counts of its job and its owner.
  void count_running(Job& job, int delta);
  // A lease ends: its seconds to the job's accounting, and to the event.
  void account(Job& job, event::LeaseEnded& ended, const Lease& lease);
  // A line of the job's history (`locus events`).
  void note(const Job& job, std::string text);
  // The id of a lease whose band runs far longer than its peers, for a
  // second lease, or null.
  const std::string* speculation_candidate(const WorkerInfo& worker) const;
  // A lease ends: out of the worker's set and its job's `solo`.
  void forget_lease(Job* job, const std::string& lease_id, const Lease& lease);
  // Keeps live_ in step with the job's state (unfinished or not).
  void track(Job& job);
  // Whether the worker carries every tag the job requires.
  static bool carries(const WorkerInfo& worker, const Job& job);
  // The first job the job waits for that has not succeeded, or null.
  const Job* waiting_for(const Job& job) const;
  // Fails the unfinished jobs that wait for `job`, which failed or was
  // cancelled (and theirs in turn).
  void fail_dependents(const Job& job);
  Result<std::optional<BandLease>> grant(Job& job, int job_band, Worker& worker, bool speculative);
  // Ends a lease with `outcome`; when no other lease of its band remains,
  // the band is queued again (first, to finish frames early). Charged
  // outcomes count against the band's attempts and the worker.
  void release(const std::string& lease_id, LeaseOutcome outcome, const std::string& why);
  void end_job(Job& job, JobState state, const std::string& error);
  void drop_leases_of(Job& job);
  double speculate_after(const Job& job) const;
  BandLease make_lease(const Job& job, int job_band, const Lease& lease,
                       const std::string& id) const;
  int frame_of(const Job& job, int job_band) const {
    return job.info.spec.frame_first + job_band / job.info.spec.bands;
  }
  int band_of(const Job& job, int job_band) const { return job_band % job.info.spec.bands; }
  // The job band (the index into Job::bands) of band `band` of `frame`.
  static int64_t job_band_of(const JobSpec& s, int frame, int band) {
    return static_cast<int64_t>(frame - s.frame_first) * s.bands + band;
  }
  std::string band_name(const Job& job, int job_band) const;

  SchedulerOptions options_;
  NowFn now_;
  std::vector<std::string> order_;  // job ids, oldest first: the order jobs() lists them in
  std::map<std::string, Job> jobs_;
  // The unfinished jobs by seq, oldest first: what dispatch, speculation
  // and the movie thread walk, however many finished jobs are kept.
  std::map<int64_t, Job*> live_;
  std::map<std::string, std::string> requests_;  // request id -> job id
  std::map<std::string, Lease> leases_;
  std::map<std::string, Worker> workers_;
  std::map<std::string, int> user_running_;  // live leases by job owner
  std::map<std::string, std::string> movies_;  // render job id -> its movie job's id
  uint64_t next_movie_run_ = 1;
  std::set<std::string> disabled_;           // worker names
  std::vector<Event> events_;
  uint64_t next_job_ = 1;
  uint64_t next_worker_ = 1;
  uint64_t next_lease_ = 1;
  std::string lease_prefix_;
  uint64_t version_ = 0;
};

}  // namespace locus::farm
