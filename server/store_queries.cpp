// The job store (store.h): its history, band records, scenes, deletions,
// and the reads of band logs and attempts for the CLI and the dashboard.
#include <fmt/format.h>
#include <sqlite3.h>

#include <string>
#include <vector>

#include "server/store.h"
#include "server/store_internal.h"

namespace locus::farm {

using store_detail::decode_stats;

Status JobStore::add_history(const std::string& job_id, int frame, int band,
                             const std::string& text) {
  Statement st(*this,
               "INSERT INTO history(seq, job_id, at, frame, band, text) VALUES(?,?,?,?,?,?)");
  st.bind(next_seq_++, job_id, wall_now(), frame, band, text);
  return st.run();
}

Result<std::vector<HistoryEntry>> JobStore::history(const std::string& job_id, int64_t after,
                                                    int limit) {
  // The history table's rows and each lease's two events from its attempts
  // row (granted; ended or done), merged by their cursor. Each arm reads an
  // index in cursor order (history_by_job, attempts_by_grant,
  // attempts_by_end), so a page costs its length, not the job's size.
  // Stores written before the leases' events moved (no grant_seq) keep
  // them as history rows, and those read as before.
  Statement st(*this,
               "SELECT seq, at, frame, band, text, 0, '', '', '', 0, 0, '', '', 0.0, 0 "
               "FROM history WHERE job_id = ?1 AND seq > ?2 "
               "UNION ALL SELECT grant_seq, started_at, frame, band, '', 1, lease_id, worker_id, "
               "worker_name, attempt, speculative, '', '', 0.0, 0 "
               "FROM attempts WHERE job_id = ?1 AND grant_seq > ?2 "
               "UNION ALL SELECT end_seq, ended_at, frame, band, '', 2, lease_id, worker_id, '', 0, "
               "0, outcome, error, seconds, requeued "
               "FROM attempts WHERE job_id = ?1 AND end_seq > ?2 "
               "ORDER BY 1 LIMIT ?3");
  st.bind(job_id, after, limit);
  std::vector<HistoryEntry> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) break;
    if (rc != SQLITE_ROW) return st.error();
    HistoryEntry h{st.integer(0), st.real(1), static_cast<int>(st.integer(2)),
                   static_cast<int>(st.integer(3)), st.text(4)};
    const int64_t kind = st.integer(5);
    const std::string lease = st.text(6), worker = st.text(7);
    if (kind == 1) {
      h.text = fmt::format("lease {}: band {} of frame {} to worker {} ({}), attempt {}{}", lease,
                           h.band, h.frame, worker, st.text(8), st.integer(9),
                           st.integer(10) ? ", speculative" : "");
    } else if (kind == 2) {
      const std::string outcome = st.text(11), error = st.text(12);
      if (outcome == "done") {
        h.text = fmt::format("lease {} done: band {} of frame {} by worker {} in {:.3f} s", lease,
                             h.band, h.frame, worker, st.real(13));
      } else {
        h.text = fmt::format("lease {} {}{}{}", lease, outcome, error.empty() ? "" : ": " + error,
                             st.integer(14) ? "; band back in the queue" : "");
      }
    }
    out.push_back(std::move(h));
  }
  return out;
}

Status JobStore::forget_band(const std::string& job_id, int frame, int band) {
  Statement st(*this,
               "UPDATE bands SET done = 0, completions = 0 WHERE job_id = ? AND frame = ? AND "
               "band = ?");
  st.bind(job_id, frame, band);
  if (Status s = st.run(); !s.ok()) return s;
  Statement px(*this, "DELETE FROM band_pixels WHERE job_id = ? AND frame = ? AND band = ?");
  px.bind(job_id, frame, band);
  return px.run();
}

Result<std::string> JobStore::band_record(const std::string& job_id, int frame, int band) {
  Statement st(*this, "SELECT pixels FROM band_pixels WHERE job_id = ? AND frame = ? AND band = ?");
  st.bind(job_id, frame, band);
  const int rc = st.step();
  if (rc == SQLITE_ROW) return st.text(0);
  if (rc == SQLITE_DONE) {
    return NotFound("band " + std::to_string(band) + " of frame " + std::to_string(frame) +
                    " of job " + job_id + " has no pixels in the store");
  }
  return st.error();
}

Status JobStore::put_band_record(const std::string& job_id, int frame, int band,
                                 const std::string& record) {
  Statement st(*this,
               "INSERT OR REPLACE INTO band_pixels(job_id, frame, band, pixels) VALUES(?,?,?,?)");
  st.bind(job_id, frame, band, Blob{record});
  return st.run();
}

Status JobStore::put_scene(const std::string& hash, const std::string& bytes) {
  Statement st(*this, "INSERT OR IGNORE INTO scenes(hash, scene) VALUES(?, ?)");
  st.bind(hash, bytes);
  return st.run();
}

Result<std::string> JobStore::scene(const std::string& hash) {
  Statement st(*this, "SELECT scene FROM scenes WHERE hash = ?");
  st.bind(hash);
  const int rc = st.step();
  if (rc == SQLITE_ROW) return st.text(0);
  if (rc == SQLITE_DONE) return NotFound("scene " + hash + " is not in the job store");
  return st.error();
}

Status JobStore::keep_scenes(const std::set<std::string>& keep) {
  std::vector<std::string> drop;
  {
    Statement st(*this, "SELECT hash FROM scenes");
    while (st.step() == SQLITE_ROW) {
      if (!keep.count(st.text(0))) drop.push_back(st.text(0));
    }
  }
  for (const std::string& h : drop) {
    Statement st(*this, "DELETE FROM scenes WHERE hash = ?");
    st.bind(h);
    if (Status s = st.run(); !s.ok()) return s;
  }
  return Status::Ok();
}

Status JobStore::delete_job(const std::string& job_id) {
  if (Status s = exec("BEGIN IMMEDIATE"); !s.ok()) return s;
  for (const char* sql :
       {"DELETE FROM history WHERE job_id = ?", "DELETE FROM band_logs WHERE job_id = ?",
        "DELETE FROM attempts WHERE job_id = ?", "DELETE FROM frames WHERE job_id = ?",
        "DELETE FROM bands WHERE job_id = ?", "DELETE FROM band_pixels WHERE job_id = ?",
        "DELETE FROM jobs WHERE id = ?"}) {
    Statement st(*this, sql);
    st.bind(job_id);
    if (Status s = st.run(); !s.ok()) {
      exec("ROLLBACK");
      return s;
    }
  }
  return exec("COMMIT");
}

// Rows of "seq, frame, band, lease_id, worker_id, text".
template <typename Statement>
static Result<std::vector<BandLogLine>> read_log_lines(Statement& st) {
  std::vector<BandLogLine> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) return out;
    if (rc != SQLITE_ROW) return st.error();
    out.push_back({st.integer(0), static_cast<int>(st.integer(1)), static_cast<int>(st.integer(2)),
                   st.text(3), st.text(4), st.text(5)});
  }
}

Result<std::vector<BandLogLine>> JobStore::band_logs(const std::string& job_id, int frame, int band,
                                                     int64_t after, int limit) {
  Statement st(*this,
               "SELECT seq, frame, band, lease_id, worker_id, text FROM band_logs WHERE job_id = ? "
               "AND seq > ? AND (? < 0 OR frame = ?) AND (? < 0 OR band = ?) ORDER BY seq LIMIT ?");
  st.bind(job_id, after, frame, frame, band, band, limit);
  return read_log_lines(st);
}

namespace {
constexpr const char* kAttemptColumns =
    "lease_id, job_id, frame, band, worker_id, worker_name, speculative, started_at, "
    "COALESCE(ended_at, 0), COALESCE(outcome, ''), error";
}  // namespace

// Rows of kAttemptColumns.
template <typename Statement>
static Result<std::vector<AttemptInfo>> read_attempts(Statement& st) {
  std::vector<AttemptInfo> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) return out;
    if (rc != SQLITE_ROW) return st.error();
    AttemptInfo a;
    a.lease_id = st.text(0);
    a.job_id = st.text(1);
    a.frame = static_cast<int>(st.integer(2));
    a.band = static_cast<int>(st.integer(3));
    a.worker_id = st.text(4);
    a.worker_name = st.text(5);
    a.speculative = st.integer(6) != 0;
    a.started_at = st.real(7);
    a.ended_at = st.real(8);
    a.outcome = st.text(9);
    a.error = st.text(10);
    out.push_back(std::move(a));
  }
}

Result<std::vector<AttemptInfo>> JobStore::frame_attempts(const std::string& job_id, int frame) {
  static const std::string sql = std::string("SELECT ") + kAttemptColumns +
                                 " FROM attempts WHERE job_id = ? AND frame = ? ORDER BY "
                                 "started_at, rowid";
  Statement st(*this, sql.c_str());
  st.bind(job_id, frame);
  return read_attempts(st);
}

Result<std::map<int, Stats>> JobStore::frame_band_stats(const std::string& job_id, int frame) {
  Statement st(*this, "SELECT band, stats FROM bands WHERE job_id = ? AND frame = ? AND done = 1");
  st.bind(job_id, frame);
  std::map<int, Stats> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) return out;
    if (rc != SQLITE_ROW) return st.error();
    out[static_cast<int>(st.integer(0))] = decode_stats(st.text(1));
  }
}

Result<std::vector<AttemptInfo>> JobStore::worker_attempts(const std::string& worker_id,
                                                           int limit) {
  static const std::string sql = std::string("SELECT ") + kAttemptColumns +
                                 " FROM attempts WHERE worker_id = ? ORDER BY started_at DESC, "
                                 "rowid DESC LIMIT ?";
  Statement st(*this, sql.c_str());
  st.bind(worker_id, limit);
  return read_attempts(st);
}

Result<std::vector<BandLogLine>> JobStore::worker_logs(const std::string& worker_id, int limit) {
  Statement st(*this,
               "SELECT seq, frame, band, lease_id, worker_id, text FROM band_logs WHERE "
               "worker_id = ? ORDER BY seq DESC LIMIT ?");
  st.bind(worker_id, limit);
  return read_log_lines(st);
}

Result<std::vector<std::string>> JobStore::jobs_finished_before(double unix_seconds) {
  Statement st(*this,
               "SELECT id FROM jobs WHERE finished_at IS NOT NULL AND finished_at < ? "
               "ORDER BY seq");
  st.bind(unix_seconds);
  std::vector<std::string> out;
  for (;;) {
    const int rc = st.step();
    if (rc == SQLITE_DONE) return out;
    if (rc != SQLITE_ROW) return st.error();
    out.push_back(st.text(0));
  }
}

Result<int> JobStore::band_completions(const std::string& job_id, int frame, int band) {
  Statement st(*this, "SELECT completions FROM bands WHERE job_id = ? AND frame = ? AND band = ?");
  st.bind(job_id, frame, band);
  const int rc = st.step();
  if (rc == SQLITE_ROW) return static_cast<int>(st.integer(0));
  if (rc == SQLITE_DONE) return 0;
  return st.error();
}

}  // namespace locus::farm
