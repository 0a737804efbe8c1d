// The coordinator's service logic: thread-safe, no gRPC. It validates
// submissions, keeps scenes by content hash, runs the Scheduler under one
// lock, holds long polls and watches on a condition variable, lapses leases
// on a ticker thread and writes finished frames on a writer thread.
// server/grpc_service.cpp adapts it to the two gRPC services.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "common/farm/auth.h"
#include "common/farm/types.h"
#include "proto/scene.pb.h"
#include "server/latency.h"
#include "server/scheduler.h"
#include "server/store.h"
#include "server/submission.h"

namespace locus::farm {

class CoordinatorMetrics;
struct CheckedSubmission;

struct CoordinatorOptions {
  // The job store (DATA/locus.db) and the pixels: DATA/jobs/<job>/bands/
  // for bands of frames in progress; frames go to ROOT/<job>/<file>.
  std::string data_dir;
  std::string output_root;  // ROOT above; empty: DATA/jobs
  std::string mesh_root;    // OBJ files a submitted scene may name; empty: none
  Limits limits;
  Millis lease{5000};
  Millis heartbeat{1000};   // asked of workers; well inside the lease
  Millis max_poll{10000};   // longest GetTask wait
  Millis max_watch{30000};  // longest single WatchJob stream
  // A watcher gets at most one update per this long (the job's end at once).
  Millis watch_interval{100};
  Millis tick{100};         // how often leases are checked
  int max_attempts = 3;
  int quarantine_after = 2;
  double speculate_factor = 3.0;
  Millis speculate_min{1000};
  Millis band_timeout{0};    // --band-timeout; 0: none
  Millis ageing{60000};      // --ageing
  int user_max_running = 0;  // --user-max-running; 0: no cap
  bool exr_zip = true;       // SchedulerOptions::exr_zip (--no-exr-zip: false)
  // --retention-days: finished jobs older than this are deleted with their
  // frames (checked every minute); 0: kept until `locus delete`.
  Millis retention{0};
  Millis retention_check{60000};  // how often (tests shorten it)
  // A band is acknowledged once durable: its record and "done" committed
  // and the store's log synced (survives a power loss); frames and their
  // directory are fsynced before the store names them. Without it a
  // kill -9 is still survived.
  bool fsync = true;
  // Group commit: the longest an accepted band waits for others to share
  // its sync (the first of a batch; later ones wait less).
  Millis group_commit{5};
  // Threads stitching and writing frames (encoding a PNG costs ~125 ns a
  // pixel: one thread writes fewer than 4 frames of 1080p a second);
  // 0: one per core, at most 8.
  int frame_writers = 0;
  // Threads answering workers' calls (server/handler_pool.h): 0, one per
  // core, at least 4, at most 32; -1, none: gRPC's own threads answer, as
  // before (for comparison, bench/farm/scale.sh).
  int handler_threads = 0;
  // A full disk (docs/farm.md "A full disk"): below this many free bytes
  // in the data directory new jobs are refused, and a coordinator whose
  // store or frames could not be written waits for at least this much
  // before it carries on.
  uint64_t min_free_bytes = 64ull << 20;
  // Cut frames into bands of equal predicted cost (common/farm/band_split.h)
  // rather than equal height; local method only.
  bool cost_bands = true;
  // ... even when the frame has many bands per worker (cost_split_pays).
  bool always_cost_bands = false;
  // The cost pre-pass: the band edges (none: equal heights) and the
  // predicted cost of each row. Tests put a slow one in its place.
  std::function<std::vector<int>(const CheckedSubmission&, std::vector<float>*)> cost_pass =
      cost_band_edges;
  // --private-jobs: a job's status, history and frames are its owner's and
  // admins' only (by default every client reads every job).
  bool private_jobs = false;
  // --notify-urls: the URLs a job may ask to be told at when it ends
  // (JobSpec::notify_url must fall under one; check_notify_url). Empty:
  // none may.
  std::vector<std::string> notify_urls;
  NowFn now = [] { return SteadyClock::now(); };
};

// Return false to stop a stream (the client has gone).
using JobSink = std::function<bool(const JobInfo&)>;
using ChunkSink = std::function<bool(const FileChunk&)>;
using CancelledFn = std::function<bool()>;

class Coordinator {
 public:
  explicit Coordinator(CoordinatorOptions options);
  ~Coordinator();
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  // Opens the job store in the data directory, resumes the jobs it holds
  // and starts the ticker and writer threads.
  Status start();
  // SIGTERM, step 1: refuses new jobs and leases no more bands (a worker's
  // long poll waits out its time empty-handed); results, heartbeats and
  // everything else go on as before.
  void drain();
  // Step 2: waits until no band is leased and every finished frame is
  // written, or `max` passes. Returns whether it got there.
  bool wait_drained(Millis max);
  // Step 3: long polls and watches end now (and new ones are refused as
  // UNAVAILABLE), so that the server's in-flight calls can finish.
  void stop_waiting();
  // Last: writes the frames already complete, records everything in the
  // store, closes it and joins the threads.
  void shutdown();
  // Tests only: stops like a kill -9 would, as far as the data directory
  // can tell: frames waiting to be written are dropped, nothing more is
  // recorded, the store is left as it is.
  void crash_for_test();

  // ---- ClientService ----
  // InvalidArgument naming the scene and the problem; nothing is stored then.
  // `owner`: the caller's user name (empty: none), recorded with the job.
  Result<JobInfo> submit(const SubmitRequest& request, const std::string& owner = "");
  // Reading, checked by may_read().
  Result<JobInfo> job(const std::string& job_id, const Caller& caller = Caller::anyone());
  std::vector<JobInfo> jobs(const Caller& caller = Caller::anyone());
  // The operators' actions (the Scheduler's), each allowed to the job's
  // owner and to admins (PERMISSION_DENIED otherwise; a job without an
  // owner, to anyone). The caller is named in the job's history.
  Result<JobInfo> cancel(const std::string& job_id, const Caller& caller = Caller::anyone());
  Result<JobInfo> set_priority(const std::string& job_id, int priority, bool preempt,
                               const Caller& caller = Caller::anyone());
  Result<JobInfo> pause(const std::string& job_id, const Caller& caller = Caller::anyone());
  Result<JobInfo> resume(const std::string& job_id, const Caller& caller = Caller::anyone());
  // `locus retry` and `locus requeue` (Scheduler::retry, requeue): the job
  // back in the queue, with its scene from the store. RESOURCE_EXHAUSTED
  // at --max-jobs unfinished jobs; FAILED_PRECONDITION when the store no
  // longer has the scene (a job that ended before scenes were kept).
  Result<JobInfo> retry(const std::string& job_id, const Caller& caller = Caller::anyone());
  Result<JobInfo> requeue(const std::string& job_id, std::optional<int> first,
                          std::optional<int> last, const Caller& caller = Caller::anyone());
  // The lines workers logged for the job's bands (`locus logs`), read like
  // events().
  Result<std::vector<BandLogLine>> logs(const std::string& job_id, int frame, int band,
                                        int64_t after, int limit,
                                        const Caller& caller = Caller::anyone());
  // `locus delete`: a finished job (FAILED_PRECONDITION otherwise) and its
  // record, history and band files; with `outputs` its frames too. Its
  // owner's or an admin's. Returns its last status.
  Result<JobInfo> delete_job(const std::string& job_id, bool outputs,
                             const Caller& caller = Caller::anyone());
  // The job's history after cursor `after`, at most `limit` lines
  // (`locus events`); NotFound for an unknown job.
  Result<std::vector<HistoryEntry>> events(const std::string& job_id, int64_t after, int limit,
                                           const Caller& caller = Caller::anyone());
  std::vector<WorkerInfo> workers();
  // The farm page: jobs (those the caller may read) and workers, with the
  // scheduler's version; nothing when `since` is that version already.
  struct Snapshot {
    uint64_t version = 0;
    bool unchanged = false;
    std::vector<JobInfo> jobs;
    std::vector<WorkerInfo> workers;
  };
  Snapshot snapshot(uint64_t since, const Caller& caller = Caller::anyone());
  // One frame's bands from the store (the band map); read like job().
  // NotFound for a frame outside the job's.
  Result<FrameDetail> frame_detail(const std::string& job_id, int frame,
                                   const Caller& caller = Caller::anyone());
  // A worker, by id or name: connected, or remembered by its leases in the
  // store. With --private-jobs only the caller's jobs' leases and lines.
  Result<WorkerDetail> worker_detail(const std::string& worker,
                                     const Caller& caller = Caller::anyone());
  // The dashboard's images, read like job(): the path of a written frame's
  // file; the pixels of an accepted band of a frame not yet written
  // (NotFound otherwise, e.g. once its frame is written). `cost_map`: the
  // path of the frame's cost map instead (NotFound for a job without).
  Result<std::string> frame_file(const std::string& job_id, int frame,
                                 const Caller& caller = Caller::anyone(), bool cost_map = false);
  Result<Image> band_image(const std::string& job_id, int frame, int band,
                           const Caller& caller = Caller::anyone());
  // A job with cost maps, a frame not yet written: the cost map of the
  // bands accepted so far (their counts joined, the others' rows empty),
  // as cost_map_image draws it; `bands_in` gets how many bands it holds.
  // NotFound for a job without cost maps, a frame out of range, or a
  // frame already written (its file is frame_file(..., true)).
  Result<Image> partial_cost_map(const std::string& job_id, int frame, int* bands_in,
                                 const Caller& caller = Caller::anyone());
  // `locus drain|disable|enable`: admins only (PERMISSION_DENIED). The
  // worker by id or name; returns its name.
  Result<std::string> drain_worker(const std::string& worker, const Caller& caller);
  Result<std::string> set_worker_disabled(const std::string& worker, bool disabled,
                                          const Caller& caller);
  // Whether the worker was asked to drain (told in heartbeats and polls).
  bool worker_draining(const std::string& worker_id);

  // ---- notifications (server/notifier.h) ----
  // `fn` gets each job that ends (its final status), under the
  // coordinator's lock: it must only queue. `every_job`: every job's end
  // (the coordinator's --notify-cmd); else only those of jobs with a
  // notify URL. Their ends are recorded as pending with the state change,
  // so start() hands `fn` those a stop left pending. Set before start().
  void on_job_ended(std::function<void(const JobInfo&)> fn, bool every_job);
  // A line of the job's history about telling its end; `done`: nothing
  // is left to tell.
  void record_notified(const std::string& job_id, const std::string& text, bool done);
  // Sends the job's status now, then on each change (throttled), until the
  // job ends, `max` passes, the client cancels or the sink refuses.
  Status watch(const std::string& job_id, const Caller& caller, Millis max,
               const CancelledFn& cancelled, const JobSink& sink);
  // Sends the written frame files; `frames` empty: all written so far.
  // `cost_maps`: the frames' cost maps instead (FailedPrecondition for a
  // job that makes none).
  Status fetch(const std::string& job_id, const Caller& caller, const std::vector<int>& frames,
               const ChunkSink& sink, bool cost_maps = false);

  // ---- WorkerService ----
  // InvalidArgument for bad tags (check_tags).
  // `offers`: the encodings the worker offers (WorkerInfo::encodings).
  Result<Registration> register_worker(const std::string& name, int threads,
                                       const std::vector<std::string>& tags = {},
                                       EncodingOffers offers = {});
  // GetTask, the long poll, without holding a thread (the gRPC callback
  // service): `done` gets the band leased to the worker as soon as there is
  // one, nothing once `wait` (capped by max_poll) has passed, or the error;
  // exactly once, never under the coordinator's lock: on this thread when
  // the answer is known at once, else on the dispatch thread. A waiting
  // poll costs an entry in a map, not a thread. Returns a ticket for
  // cancel_poll().
  using PollAnswer = Result<std::optional<BandLease>>;
  using PollDone = std::function<void(PollAnswer)>;
  uint64_t poll_band(const std::string& worker_id, Millis wait, PollDone done);
  // Up to `n` further bands for a worker that has just been given one
  // (GetTaskRequest.max_bands), leased at once as poll_band's first try
  // would, each under its own lease; fewer (or none) when the queue holds
  // no more for it.
  std::vector<BandLease> lease_more(const std::string& worker_id, int n);
  // The caller went away: its poll ends now with nothing (a no-op once
  // it was answered).
  void cancel_poll(uint64_t ticket);
  // A worker's call came in (any call naming it): it counts as seen at the
  // next tick, before any worker is dropped for silence, however long the
  // call then waits for a handler (docs/farm.md "Under load"). Does not
  // take mu_.
  void worker_call_arrived(const std::string& worker_id);
  // poll_band() for a caller with a thread to spare (tests, tools):
  // returns its answer; `cancelled` is asked every 200 ms.
  PollAnswer lease_band(const std::string& worker_id, Millis wait, const CancelledFn& cancelled);
  // The scene of content hash `hash`, serialized (a v1::Scene message).
  Result<std::shared_ptr<const std::string>> get_scene(const std::string& worker_id,
                                                       const std::string& hash);
  // CompleteBand without holding a thread: `done` gets the outcome exactly
  // once, never under the lock. An accepted band's is given once the band
  // is durable (group commit, commit_loop()); a refusal's at once.
  using CompleteDone = std::function<void(Result<CompleteOutcome>)>;
  void complete_band_async(BandOutput output, CompleteDone done);
  // Several results of one call (CompleteBandRequest.more), each judged
  // alone and told through its own `dones[i]`, under the coordinator's lock
  // twice in all rather than twice each.
  void complete_bands_async(std::vector<BandOutput> outputs, std::vector<CompleteDone> dones);
  // The same, waiting here (tests, tools).
  Result<CompleteOutcome> complete_band(BandOutput output);
  // Syncs of the store's log made by the group commit (the benchmark's
  // "syncs per band").
  uint64_t log_syncs() const { return log_syncs_.load(std::memory_order_relaxed); }
  Result<std::vector<std::string>> heartbeat(const std::string& worker_id,
                                             const std::vector<std::string>& lease_ids);

  // The directory holding a job's frames, under the output root.
  std::string job_dir(const std::string& job_id) const;
  // Time from a band being available to a worker to its lease, over the
  // coordinator's life (GetTask calls that returned a band).
  LatencySummary dispatch_latency();
  std::string output_root() const;

  // The Prometheus series (server/metrics.h); refresh_metrics() sets the
  // gauges from the scheduler, as each scrape does first.
  CoordinatorMetrics& metrics() { return *metrics_; }
  const CoordinatorOptions& options() const { return options_; }
  void refresh_metrics();
  // refresh_metrics(), then the text exposition format (GET /metrics).
  std::string metrics_text();

 private:
  Status recover();  // start(), before the threads
  // submit()'s steps under mu_, after check_submission() and the
  // fingerprint (server/submission.h): the answer when the farm refuses
  // the job now or it is a retry (answered with its first job), else
  // none; a retry's answer; the band count; the job stored, then
  // scheduled. The band edges are cut between them, outside mu_.
  std::optional<Result<JobInfo>> refused_or_retried(const SubmitRequest& r,
                                                    const CheckedSubmission& job,
                                                    const std::string& fingerprint);
  Result<JobInfo> resubmitted(const JobRecord& earlier, const std::string& request_id,
                              const std::string& fingerprint);
  Status count_bands(int bands, CheckedSubmission& job);
  Result<JobInfo> record_job(const JobSpec& spec, std::shared_ptr<const std::string> scene,
                             const std::string& request_id, const std::string& fingerprint);
  void tick_loop();
  // Group commit of accepted bands: persist(), sync_log(), acknowledge.
  void commit_loop();
  // fdatasync of the store's write-ahead log; outside mu_.
  Status sync_log();
  // A band's record through the reader connection (the writer thread, the
  // dashboard), outside mu_.
  Result<std::string> read_band_record(const std::string& job_id, int frame, int band);
  void close_store_files();  // with the store: the reader, the log's descriptor
  // Answers the parked polls (poll_band) as bands become available, their
  // time runs out or the coordinator stops.
  void dispatch_loop();
  // What a poll gets now: a lease, an error, "nothing, and stop waiting"
  // (a drained worker), or nullopt to keep waiting; mu_ held.
  std::optional<PollAnswer> try_lease(const std::string& worker_id);
  // One pass of dispatch_loop() over the parked polls; `all`: every poll
  // is looked at (a drain, a stop), else only while bands are queued.
  // The answers are run by the caller once mu_ is released.
  void serve_polls(bool all, std::vector<std::pair<PollDone, PollAnswer>>& answers);
  void write_loop();
  // Makes the movie jobs (Scheduler::next_movie) with ffmpeg, one at a
  // time, outside the lock (common/farm/movie.h).
  void movie_loop();
  // A render job's movie job (JobSpec::movie), recorded with it; mu_ held.
  JobSpec movie_spec(const JobSpec& render, const std::string& render_id) const;
  void drop_unused_scenes();  // mu_ held
  // The scene into scenes_ from the store, unless there; mu_ held.
  Status load_scene(const std::string& hash, const std::string& job_id);
  // retry's and requeue's common steps; mu_ held.
  Result<JobInfo> reopen(const std::string& job_id,
                         const std::function<Result<Scheduler::Reopened>()>& call);
  // Whether the frame is queued for the writer or being written; mu_ held.
  bool write_pending(const std::string& job_id, int frame) const;
  // delete_job's work once allowed; mu_ held.
  Status remove_job(const JobInfo& job, bool outputs);
  void apply_retention();  // mu_ held
  // Hands the Scheduler's events to the store in one transaction; mu_ held.
  // When it fails they are kept (unstored_) for the next one, and the
  // coordinator is in storage trouble.
  Status persist();
  // ---- storage trouble (server/coordinator_commit.cpp); mu_ held
  uint64_t free_bytes() const;  // in the data directory
  // The error a client or worker gets while in trouble (Ok otherwise).
  Status storage_refusal(const char* what) const;
  void storage_failed(const Status& why);  // enters it, logs it once
  // The ticker's: out of it once space is back and what was kept is stored.
  void check_storage();
  // A frame whose write failed for want of space waits (true), else false.
  bool hold_frame(const FrameReady& f, const Status& written);
  // PERMISSION_DENIED when --private-jobs hides the job from the caller.
  Status may_read(const JobInfo& job, const Caller& caller) const;
  // An action on one job under mu_: the Scheduler's call, then the store.
  Result<JobInfo> act(const std::string& job_id, const char* what, const Caller& caller,
                      const std::function<Result<JobInfo>(const std::string& who)>& call);

  CoordinatorOptions options_;
  // worker_call_arrived(): the workers heard from since the last tick.
  std::mutex arrivals_mu_;
  std::set<std::string> arrivals_;
  std::mutex mu_;
  std::condition_variable changed_;  // scheduler version moved, or stopping
  Scheduler scheduler_;
  int lock_fd_ = -1;  // flock on DATA/coordinator.lock
  std::unique_ptr<JobStore> store_;
  // Serialized scenes (v1::Scene) by content hash, as GetScene sends them.
  std::map<std::string, std::shared_ptr<const std::string>> scenes_;
  std::set<std::string> scenes_stored_;  // the store's scenes, as last trimmed
  std::deque<FrameReady> to_write_;
  LatencyHistogram dispatch_;
  std::unique_ptr<CoordinatorMetrics> metrics_;
  std::condition_variable write_ready_;
  std::list<FrameReady> writing_;  // the frames the writer threads hold
  bool draining_ = false;          // drain()
  bool closing_ = false;           // stop_waiting()
  bool stopping_ = false;
  bool crashed_ = false;  // crash_for_test()
  bool started_ = false;
  // Parked GetTask calls (poll_band), oldest first, and by their end.
  struct Poll {
    std::string worker_id;
    TimePoint end;
    TimePoint since;  // the call, or the last pass that looked at it
    PollDone done;
  };
  std::map<uint64_t, Poll> polls_;
  std::set<std::pair<TimePoint, uint64_t>> poll_ends_;
  uint64_t next_poll_ = 1;
  bool polls_all_ = false;      // every parked poll must be looked at (drain, stop)
  bool speculate_due_ = false;  // a tick has passed: the oldest poll may speculate
  // Accepted bands waiting for their batch to be durable.
  struct Commit {
    CompleteDone done;
    CompleteOutcome outcome;
    std::optional<FrameReady> frame;  // the frame they complete, written after the commit
    TimePoint queued;
  };
  std::deque<Commit> commits_;
  std::condition_variable commit_ready_;
  // Storage trouble: the store's last transaction failed, or a frame found
  // no space (Ok: none). Meanwhile no job is accepted, no band leased and
  // no result taken; the failed transaction's events wait in unstored_,
  // the frames to write in held_frames_.
  Status storage_trouble_;
  TimePoint trouble_checked_{};
  bool storage_retry_ = false;  // check_storage(): persist() may try the store
  std::vector<Event> unstored_;
  std::deque<FrameReady> held_frames_;
  // Records of accepted bands, until persist() puts them with their "done".
  std::map<std::tuple<std::string, int, int>, std::string> band_records_;
  int log_fd_ = -1;  // the WAL, for sync_log(); the commit thread's
  std::atomic<uint64_t> log_syncs_{0};
  std::mutex reader_mu_;
  std::unique_ptr<JobStore> reader_;
  std::thread ticker_;
  std::thread dispatcher_;
  std::thread committer_;
  std::vector<std::thread> writers_;  // write_loop(), frame_writers of them
  std::thread movie_maker_;
  std::function<void(const JobInfo&)> job_ended_;  // on_job_ended()
  bool notify_every_job_ = false;
};

}  // namespace locus::farm
