// What the Scheduler tells its durable store, and what the store gives back
// after a restart. The Scheduler stays a plain single-threaded class: it
// only appends events; the Coordinator hands them to the JobStore
// (server/store.h) in one transaction after each call. No SQLite here.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "common/base/labels.h"
#include "common/farm/types.h"

namespace locus::farm {

// Seconds since the epoch, the store's and the history's times.
inline double wall_now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// How a lease ended (the `outcome` column of the attempts table).
enum class LeaseOutcome {
  kDone,        // its result was accepted
  kFailed,      // the worker reported an error
  kMalformed,   // the worker sent pixels of the wrong size
  kLapsed,      // not renewed in time
  kSilent,      // the worker went silent and was dropped
  kHandedBack,  // the worker gave it back (SIGTERM)
  kDiscarded,   // another lease of the band won the race
  kRevoked,     // the job was cancelled or failed
  kTimedOut,    // leased longer than the band timeout (a hung band)
  kPreempted,   // handed back for a job of higher priority (`locus priority --preempt`)
};
// The `outcome` column's words and the metrics' `reason` label.
inline constexpr Labels<LeaseOutcome, 10> kLeaseOutcomeLabels = {
    {{LeaseOutcome::kDone, "done"},
     {LeaseOutcome::kFailed, "failed"},
     {LeaseOutcome::kMalformed, "malformed"},
     {LeaseOutcome::kLapsed, "lapsed"},
     {LeaseOutcome::kSilent, "silent"},
     {LeaseOutcome::kHandedBack, "handed back"},
     {LeaseOutcome::kDiscarded, "discarded"},
     {LeaseOutcome::kRevoked, "revoked"},
     {LeaseOutcome::kTimedOut, "timed out"},
     {LeaseOutcome::kPreempted, "preempted"}}};
// A C string: every name in the table (and the fallback) is a literal.
inline const char* lease_outcome_name(LeaseOutcome outcome) {
  return label_name(kLeaseOutcomeLabels, outcome).data();
}
// Whether the outcome counts as one of the band's failed attempts.
bool is_charged(LeaseOutcome outcome);

// A job as stored: the spec plus what makes a submission idempotent.
struct JobRecord {
  std::string job_id;
  int64_t seq = 0;          // j0001 has 1
  std::string request_id;   // the client's token; empty: none
  std::string fingerprint;  // of the request, to tell a retry from a reuse of the token
  JobSpec spec;
};

namespace event {
struct JobAdded {
  JobRecord job;
};
struct JobStateChanged {
  std::string job_id;
  JobState state;
  std::string error;
};
struct LeaseGranted {
  std::string lease_id;
  std::string job_id;
  int frame = 0;
  int band = 0;
  std::string worker_id;
  std::string worker_name;
  bool speculative = false;
  // When it was granted (wall_now()): its history line's time, not the
  // later one of the transaction that stores it (a lease granted with a
  // result's answer is stored by the next). 0: the store's time.
  double granted_at = 0;
};
struct LeaseEnded {
  std::string lease_id;
  std::string job_id;
  int frame = 0;
  int band = 0;
  LeaseOutcome outcome = LeaseOutcome::kRevoked;
  std::string error;
  bool requeued = false;    // the band went back to the queue (not the store's concern)
  double seconds = 0;       // from the lease to its end
  std::string owner;        // the job's (the metrics' user label)
  BandSeconds job_account;  // the job's total after this lease
};
// The band's pixels are in its band file; the lease that delivered them ends.
struct BandDone {
  std::string job_id;
  int frame = 0;
  int band = 0;
  std::string lease_id;
  std::string worker_id;
  Stats job_stats;          // the job's total after this band
  double seconds = 0;       // from the lease to the result
  std::string owner;        // the job's (the metrics' user label)
  double cpu_seconds = 0;   // this band's render CPU time
  BandSeconds job_account;  // the job's total after this band
  Stats band_stats;         // this band's (the dashboard's band map)
  // The band's pixels as the store keeps them (band_files.h pack_band),
  // recorded with its "done"; set by the coordinator, not the Scheduler.
  std::string pixels;
};
struct FrameWritten {
  std::string job_id;
  int frame = 0;
  std::string file_name;
};
struct WorkerAdded {
  uint64_t next_worker = 0;  // worker numbers never repeat across runs
};
struct PriorityChanged {
  std::string job_id;
  int priority = kDefaultPriority;
};
// The lines a worker logged for a band, sent with its result or failure.
struct BandLog {
  std::string job_id;
  int frame = 0;
  int band = 0;
  std::string lease_id;
  std::string worker_id;
  std::vector<std::string> lines;
};
// `locus disable` / `locus enable` of a worker name.
struct WorkerDisabled {
  std::string name;
  bool disabled = true;
};
// `locus retry` / `locus requeue`: the job is unfinished again (`state`).
// The written frames in `frames` render again (their bands are no longer
// done); `fresh_attempts`: the charged failures of its bands are forgiven.
struct JobReopened {
  std::string job_id;
  JobState state = JobState::kQueued;
  std::vector<int> frames;
  bool fresh_attempts = false;
};
// A line of the job's history that no other event words (an operator's
// action, who did it).
struct JobNote {
  std::string job_id;
  std::string text;
};
// The job's end is to be told (--notify-url, --notify-cmd: kPending, with
// its state change), a line of how the telling went (`text`), or all of it
// done (kDone): a restart tells what was still pending.
enum class NotifyPhase { kPending, kNote, kDone };
struct JobNotified {
  std::string job_id;
  NotifyPhase phase = NotifyPhase::kNote;
  std::string text;  // a line of the job's history; empty: none
};
}  // namespace event

using Event =
    std::variant<event::JobAdded, event::JobStateChanged, event::LeaseGranted, event::LeaseEnded,
                 event::BandDone, event::FrameWritten, event::WorkerAdded, event::PriorityChanged,
                 event::JobNote, event::WorkerDisabled, event::BandLog, event::JobReopened,
                 event::JobNotified>;

// A job as the store remembers it, for Scheduler::restore().
struct RecoveredJob {
  JobRecord record;
  JobState state = JobState::kQueued;
  std::string error;
  double seconds_elapsed = 0;
  Stats stats;
  BandSeconds account;
  int64_t bands_done = 0;
  int64_t results_discarded = 0;
  int64_t speculative_leases = 0;
  std::vector<int> frames_written;
  bool notify_pending = false;  // its end is still to be told (event::JobNotified)
  // Jobs that did not succeed: the bands whose pixels are on disk;
  // unfinished jobs only: the charged failures (for the attempt limit,
  // "another worker where possible" and quarantine).
  struct BandRef {
    int frame = 0;
    int band = 0;
  };
  std::vector<BandRef> done_bands;
  struct Failure {
    int frame = 0;
    int band = 0;
    std::string worker_name;
    std::string error;
  };
  std::vector<Failure> failures;
};

struct RecoveredState {
  std::vector<RecoveredJob> jobs;  // oldest first
  uint64_t next_worker = 1;
  int64_t leases_voided = 0;                  // leases of the previous run, ended at load
  std::vector<std::string> disabled_workers;  // names
};

}  // namespace locus::farm
