// The coordinator's durable job store: one SQLite database in WAL mode,
// DATA/locus.db, holding jobs, scenes, bands, frames and attempts (a lease
// is an attempt without an outcome; the `leases` view lists them). The
// Scheduler's events are applied in one transaction per call, so a
// kill -9 at any moment leaves the store at the end of some call: never a
// half-recorded band. docs/farm.md "The job store" has the schema and the
// recovery rules.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/base/status.h"
#include "server/journal.h"

struct sqlite3;
struct sqlite3_stmt;

namespace locus::farm {

class JobStore {
 public:
  // Opens (creating when new) the database at `path`.
  // `sync` false (a coordinator without --fsync, such as the embedded
  // farm's): SQLite syncs nothing either (synchronous=OFF), its
  // checkpoints included; a kill -9 is still survived, a power loss not.
  static Result<std::unique_ptr<JobStore>> open(const std::string& path, bool sync = true);
  // A second connection to the same database that only reads (the frame
  // writer's, so that reading a frame's pixels does not hold the
  // coordinator's lock). WAL: it sees every committed transaction.
  static Result<std::unique_ptr<JobStore>> open_reader(const std::string& path);
  ~JobStore();
  JobStore(const JobStore&) = delete;
  JobStore& operator=(const JobStore&) = delete;

  // Everything in one transaction: all of it or none.
  Status apply(const std::vector<Event>& events);

  // What a restart resumes. Leases of the previous run are ended ("void",
  // not charged to the band: the coordinator, not the worker, went away).
  Result<RecoveredState> recover();
  // A band the store says is done but whose band file is missing or torn
  // (possible only after a power loss): back to not done.
  Status forget_band(const std::string& job_id, int frame, int band);
  // A done band's record (server/band_files.h pack_band), kept with the
  // band's "done" (event::BandDone::pixels) until its frame is written.
  // NotFound when there is none.
  Result<std::string> band_record(const std::string& job_id, int frame, int band);
  // Imports a record (a 0.13 band file at restart).
  Status put_band_record(const std::string& job_id, int frame, int band, const std::string& record);

  Status put_scene(const std::string& hash, const std::string& bytes);
  Result<std::string> scene(const std::string& hash);
  // Drops the scenes no longer in `keep`.
  Status keep_scenes(const std::set<std::string>& keep);

  // The job's history after `after` (a HistoryEntry::seq), oldest first, at
  // most `limit` lines.
  Result<std::vector<HistoryEntry>> history(const std::string& job_id, int64_t after, int limit);

  // The lines workers logged for the job's bands after cursor `after`, of
  // one frame and band (-1: any), oldest first, at most `limit`.
  Result<std::vector<BandLogLine>> band_logs(const std::string& job_id, int frame, int band,
                                             int64_t after, int limit);
  // The leases of one frame's bands, oldest first (the band map).
  Result<std::vector<AttemptInfo>> frame_attempts(const std::string& job_id, int frame);
  // The stats of the frame's accepted bands, by band.
  Result<std::map<int, Stats>> frame_band_stats(const std::string& job_id, int frame);
  // A worker's latest leases and log lines, newest first, at most `limit`.
  Result<std::vector<AttemptInfo>> worker_attempts(const std::string& worker_id, int limit);
  Result<std::vector<BandLogLine>> worker_logs(const std::string& worker_id, int limit);

  // Removes the job and everything recorded of it, in one transaction.
  Status delete_job(const std::string& job_id);
  // Ids of the jobs that ended before `unix_seconds` (retention).
  Result<std::vector<std::string>> jobs_finished_before(double unix_seconds);

  // For tests and tools: times a band's result was accepted (0 if never).
  Result<int> band_completions(const std::string& job_id, int frame, int band);

 private:
  explicit JobStore(sqlite3* db) : db_(db) {}
  Status exec(const char* sql);
  Status apply_one(const Event& e);
  // The job rows' running totals, written once per transaction (apply())
  // rather than once per band: the last value of each job's in the batch.
  struct JobTotals {
    std::optional<std::pair<std::string, double>> stats;  // encoded stats, band_seconds
    std::optional<std::pair<double, double>> failed_lost;  // band_seconds_failed, _lost
  };
  Status write_job_totals();
  std::map<std::string, JobTotals> job_totals_;
  // The next history cursor (HistoryEntry::seq): one sequence for the
  // history table's rows and the leases' events kept in `attempts`
  // (grant_seq, end_seq), so that history() merges them in order.
  int64_t next_seq_ = 1;
  Status add_history(const std::string& job_id, int frame, int band, const std::string& text);
  class Statement;
  sqlite3* db_;
  std::map<std::string, sqlite3_stmt*> cache_;  // by SQL text
};

}  // namespace locus::farm
