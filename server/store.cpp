#include "server/store.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <sstream>
#include <string_view>
#include <tuple>

#include "server/syncs.h"

namespace locus::farm {
namespace {

// Schema version 1. Times are Unix seconds (wall clock): they survive a
// restart, where the scheduler's steady clock does not.
constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS scenes(hash TEXT PRIMARY KEY, scene BLOB NOT NULL);
CREATE TABLE IF NOT EXISTS jobs(
  seq INTEGER PRIMARY KEY,
  id TEXT NOT NULL UNIQUE,
  request_id TEXT UNIQUE,
  fingerprint TEXT NOT NULL DEFAULT '',
  scene_hash TEXT NOT NULL,
  scene_name TEXT NOT NULL,
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  frame_first INTEGER NOT NULL, frame_last INTEGER NOT NULL,
  bands INTEGER NOT NULL,
  output TEXT NOT NULL,
  orbit REAL NOT NULL,
  method TEXT NOT NULL, boxes TEXT NOT NULL, spp INTEGER NOT NULL,
  band_edges TEXT NOT NULL DEFAULT '',
  state TEXT NOT NULL,
  error TEXT NOT NULL DEFAULT '',
  submitted_at REAL NOT NULL,
  finished_at REAL,
  stats TEXT NOT NULL DEFAULT '',
  aa INTEGER NOT NULL DEFAULT -1,
  tess_tol REAL NOT NULL DEFAULT 0.25);
CREATE TABLE IF NOT EXISTS bands(
  job_id TEXT NOT NULL, frame INTEGER NOT NULL, band INTEGER NOT NULL,
  done INTEGER NOT NULL DEFAULT 0,
  completions INTEGER NOT NULL DEFAULT 0,
  failures INTEGER NOT NULL DEFAULT 0,
  last_error TEXT NOT NULL DEFAULT '',
  lease_id TEXT, worker_id TEXT,
  PRIMARY KEY(job_id, frame, band)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS frames(
  job_id TEXT NOT NULL, frame INTEGER NOT NULL, file TEXT NOT NULL, written_at REAL NOT NULL,
  PRIMARY KEY(job_id, frame)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS attempts(
  lease_id TEXT PRIMARY KEY,
  job_id TEXT NOT NULL, frame INTEGER NOT NULL, band INTEGER NOT NULL,
  worker_id TEXT NOT NULL, worker_name TEXT NOT NULL,
  speculative INTEGER NOT NULL DEFAULT 0,
  started_at REAL NOT NULL,
  ended_at REAL,
  outcome TEXT,
  error TEXT NOT NULL DEFAULT '',
  charged INTEGER NOT NULL DEFAULT 0);
CREATE INDEX IF NOT EXISTS attempts_by_band ON attempts(job_id, frame, band);
CREATE INDEX IF NOT EXISTS attempts_by_worker ON attempts(worker_id, started_at);
CREATE TABLE IF NOT EXISTS history(
  seq INTEGER PRIMARY KEY,
  job_id TEXT NOT NULL, at REAL NOT NULL,
  frame INTEGER NOT NULL DEFAULT -1, band INTEGER NOT NULL DEFAULT -1,
  text TEXT NOT NULL);
CREATE INDEX IF NOT EXISTS history_by_job ON history(job_id, seq);
CREATE TABLE IF NOT EXISTS disabled_workers(name TEXT PRIMARY KEY);
CREATE TABLE IF NOT EXISTS band_pixels(
  job_id TEXT NOT NULL, frame INTEGER NOT NULL, band INTEGER NOT NULL,
  pixels BLOB NOT NULL,
  PRIMARY KEY(job_id, frame, band));
CREATE TABLE IF NOT EXISTS band_logs(
  seq INTEGER PRIMARY KEY,
  job_id TEXT NOT NULL, frame INTEGER NOT NULL, band INTEGER NOT NULL,
  lease_id TEXT NOT NULL, worker_id TEXT NOT NULL, text TEXT NOT NULL);
CREATE INDEX IF NOT EXISTS band_logs_by_job ON band_logs(job_id, seq);
CREATE INDEX IF NOT EXISTS band_logs_by_worker ON band_logs(worker_id, seq);
CREATE VIEW IF NOT EXISTS leases AS
  SELECT lease_id, job_id, frame, band, worker_id, worker_name, speculative, started_at
  FROM attempts WHERE outcome IS NULL;
INSERT OR IGNORE INTO meta(key, value) VALUES('schema', '1');
)sql";

// Stats as one line of text: the fields in declaration order, then the
// shadow method, then what later versions added (each read if present).
std::string encode_stats(const Stats& s) {
  std::ostringstream o;
  o.precision(17);
  o << s.seconds_prepare << ' ' << s.seconds_render << ' ' << s.rays_eye << ' ' << s.rays_reflected
    << ' ' << s.rays_refracted << ' ' << s.rays_shadow << ' ' << s.tests_ray_object << ' '
    << s.tests_shadow_volume << ' ' << s.pixels_total << ' ' << s.pixels_ray_traced << ' '
    << s.spans_total << ' ' << s.spans_ray_traced << ' ' << s.shadow_method << ' '
    << s.seconds_tessellate << ' ' << s.geometry_triangles << ' ' << s.seconds_render_cpu << ' '
    << s.visibility;
  return o.str();
}

Stats decode_stats(const std::string& text) {
  Stats s;
  std::istringstream i(text);
  i >> s.seconds_prepare >> s.seconds_render >> s.rays_eye >> s.rays_reflected >>
      s.rays_refracted >> s.rays_shadow >> s.tests_ray_object >> s.tests_shadow_volume >>
      s.pixels_total >> s.pixels_ray_traced >> s.spans_total >> s.spans_ray_traced >>
      s.shadow_method;
  if (!i && !text.empty()) return Stats();
  // Written by later versions only: absent in older stores.
  double tessellate = 0;
  uint64_t triangles = 0;
  if (i >> tessellate >> triangles) {
    s.seconds_tessellate = tessellate;
    s.geometry_triangles = triangles;
  }
  double cpu = 0;
  if (i >> cpu) s.seconds_render_cpu = cpu;
  std::string visibility;
  if (i >> visibility) s.visibility = visibility;
  return s;
}

// Row costs as text: "%.4g" numbers separated by spaces (relative units:
// four digits are plenty for a chart).
std::string costs_text(const std::vector<float>& costs) {
  std::string out;
  char buf[32];
  for (float c : costs) {
    std::snprintf(buf, sizeof buf, out.empty() ? "%.4g" : " %.4g", static_cast<double>(c));
    out += buf;
  }
  return out;
}

std::vector<float> costs_from_text(const std::string& text) {
  std::vector<float> out;
  std::istringstream i(text);
  float c = 0;
  while (i >> c) out.push_back(c);
  return out;
}

// A word the table lacks (a damaged row) reads as a failed job.
JobState state_from_name(const std::string& n) {
  return label_value(kJobStateLabels, n).value_or(JobState::kFailed);
}

// The SQL below names these outcomes in its text; the table is the word's
// one home.
static_assert(label_name(kLeaseOutcomeLabels, LeaseOutcome::kDone) == "done");
static_assert(label_name(kLeaseOutcomeLabels, LeaseOutcome::kDiscarded) == "discarded");

}  // namespace

// A prepared statement, finalized on scope exit. Binding is by position
// (1-based) through bind(); step() returns SQLITE_ROW / SQLITE_DONE.
// Statements are prepared once per store and kept (keyed by their SQL).
// Bytes bound as a BLOB (pixels), not as text.
struct Blob {
  std::string_view bytes;
};

class JobStore::Statement {
 public:
  Statement(JobStore& store, const char* sql) : db_(store.db_) {
    auto it = store.cache_.find(sql);
    if (it != store.cache_.end()) {
      stmt_ = it->second;
      return;
    }
    rc_ = sqlite3_prepare_v2(db_, sql, -1, &stmt_, nullptr);
    if (rc_ == SQLITE_OK) store.cache_.emplace(sql, stmt_);
  }
  ~Statement() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  template <typename... Args>
  Statement& bind(const Args&... args) {
    int i = 0;
    (bind_one(++i, args), ...);
    return *this;
  }
  int step() {
    if (rc_ != SQLITE_OK) return rc_;
    return sqlite3_step(stmt_);
  }
  // Runs a statement that returns no rows.
  Status run() {
    const int rc = step();
    if (rc != SQLITE_DONE && rc != SQLITE_ROW) return error();
    return Status::Ok();
  }
  Status error() const { return Internal(std::string("job store: ") + sqlite3_errmsg(db_)); }
  int64_t integer(int col) const { return sqlite3_column_int64(stmt_, col); }
  double real(int col) const { return sqlite3_column_double(stmt_, col); }
  bool null(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
  std::string text(int col) const {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, col));
    return p ? std::string(p, sqlite3_column_bytes(stmt_, col)) : std::string();
  }

 private:
  void bind_one(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void bind_one(int i, int v) { sqlite3_bind_int64(stmt_, i, v); }
  void bind_one(int i, bool v) { sqlite3_bind_int64(stmt_, i, v ? 1 : 0); }
  void bind_one(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void bind_one(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  void bind_one(int i, const char* v) { sqlite3_bind_text(stmt_, i, v, -1, SQLITE_TRANSIENT); }
  void bind_one(int i, std::nullptr_t) { sqlite3_bind_null(stmt_, i); }
  void bind_one(int i, const Blob& v) {
    sqlite3_bind_blob64(stmt_, i, v.bytes.data(), v.bytes.size(), SQLITE_STATIC);
  }

  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
  int rc_ = SQLITE_OK;
};

Result<std::unique_ptr<JobStore>> JobStore::open_reader(const std::string& path) {
  sqlite3* db = nullptr;
  const int rc =
      sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string why = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    sqlite3_close(db);
    return FailedPrecondition(path + ": cannot open the job store to read: " + why);
  }
  sqlite3_busy_timeout(db, 5000);
  return std::unique_ptr<JobStore>(new JobStore(db));
}

Result<std::unique_ptr<JobStore>> JobStore::open(const std::string& path) {
  count_store_syncs();  // SQLite's syncs counted with the coordinator's (server/syncs.h)
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(
      path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    const std::string why = db ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    sqlite3_close(db);
    return FailedPrecondition(path + ": cannot open the job store: " + why);
  }
  std::unique_ptr<JobStore> store(new JobStore(db));
  sqlite3_busy_timeout(db, 5000);
  // WAL: readers (`sqlite3 DATA/locus.db`, the frame writer, the fault
  // tests) never block the coordinator. synchronous=NORMAL: a commit
  // survives a crash of the process (kill -9) at once; it survives a power
  // loss once the WAL is synced, which the coordinator's group commit does
  // for a batch of bands before it acknowledges them (sync_log(); the same
  // sync synchronous=FULL would do at each commit), and SQLite's checkpoints
  // do for the rest.
  if (Status s = store->exec("PRAGMA journal_mode=WAL"); !s.ok()) return s;
  if (Status s = store->exec("PRAGMA synchronous=NORMAL"); !s.ok()) return s;
  if (Status s = store->exec(kSchema); !s.ok())
    return FailedPrecondition(path + ": " + s.message());
  Statement check(*store, "SELECT value FROM meta WHERE key = 'schema'");
  if (check.step() != SQLITE_ROW || check.text(0) != "1") {
    return FailedPrecondition(path + ": a job store of another version; use another --data");
  }
  // Columns added since schema 1 was first written: a store from before
  // them gets them with the defaults (jobs then used).
  for (const auto& [table, column, definition] :
       {std::tuple{"bands", "stats", "stats TEXT NOT NULL DEFAULT ''"},
        {"jobs", "row_costs", "row_costs TEXT NOT NULL DEFAULT ''"},
        {"jobs", "aa", "aa INTEGER NOT NULL DEFAULT -1"},
        {"jobs", "tess_tol", "tess_tol REAL NOT NULL DEFAULT 0.25"},
        {"jobs", "band_edges", "band_edges TEXT NOT NULL DEFAULT ''"},
        {"jobs", "priority", "priority INTEGER NOT NULL DEFAULT 50"},
        {"jobs", "frame_order", "frame_order TEXT NOT NULL DEFAULT ''"},
        {"jobs", "band_timeout_ms", "band_timeout_ms INTEGER NOT NULL DEFAULT 0"},
        {"jobs", "owner", "owner TEXT NOT NULL DEFAULT ''"},
        {"jobs", "require_tags", "require_tags TEXT NOT NULL DEFAULT ''"},
        {"jobs", "after_jobs", "after_jobs TEXT NOT NULL DEFAULT ''"},
        {"jobs", "band_seconds", "band_seconds REAL NOT NULL DEFAULT 0"},
        {"jobs", "band_seconds_failed", "band_seconds_failed REAL NOT NULL DEFAULT 0"},
        {"jobs", "band_seconds_lost", "band_seconds_lost REAL NOT NULL DEFAULT 0"},
        {"jobs", "kind", "kind TEXT NOT NULL DEFAULT 'render'"},
        {"jobs", "movie", "movie TEXT NOT NULL DEFAULT ''"},
        {"jobs", "fps", "fps INTEGER NOT NULL DEFAULT 0"},
        {"jobs", "notify_url", "notify_url TEXT NOT NULL DEFAULT ''"},
        {"jobs", "notify_pending", "notify_pending INTEGER NOT NULL DEFAULT 0"},
        // A lease's events live in its attempts row, not as two history
        // rows of text (issue #25 "compact history"): its cursors in the
        // history's sequence, its attempt number, the render time reported
        // with its result, whether its band went back to the queue.
        {"attempts", "grant_seq", "grant_seq INTEGER"},
        {"attempts", "end_seq", "end_seq INTEGER"},
        {"attempts", "attempt", "attempt INTEGER NOT NULL DEFAULT 0"},
        {"attempts", "seconds", "seconds REAL NOT NULL DEFAULT 0"},
        {"attempts", "requeued", "requeued INTEGER NOT NULL DEFAULT 0"}}) {
    Statement has(*store, "SELECT COUNT(*) FROM pragma_table_info(?) WHERE name = ?");
    has.bind(table, column);
    if (has.step() != SQLITE_ROW) return has.error();
    if (has.integer(0) == 0) {
      const std::string alter =
          std::string("ALTER TABLE ") + table + " ADD COLUMN " + definition;
      if (Status s = store->exec(alter.c_str()); !s.ok()) return s;
    }
  }
  if (Status s = store->exec(
          "CREATE INDEX IF NOT EXISTS attempts_by_grant ON attempts(job_id, grant_seq);"
          "CREATE INDEX IF NOT EXISTS attempts_by_end ON attempts(job_id, end_seq);");
      !s.ok()) {
    return s;
  }
  Statement seq(*store,
                "SELECT MAX(IFNULL((SELECT MAX(seq) FROM history), 0), "
                "IFNULL((SELECT MAX(grant_seq) FROM attempts), 0), "
                "IFNULL((SELECT MAX(end_seq) FROM attempts), 0))");
  if (seq.step() != SQLITE_ROW) return seq.error();
  store->next_seq_ = seq.integer(0) + 1;
  return store;
}

JobStore::~JobStore() {
  for (auto& [sql, stmt] : cache_) sqlite3_finalize(stmt);
  sqlite3_close(db_);
}

Status JobStore::exec(const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string why = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    return Internal("job store: " + why);
  }
  return Status::Ok();
}

Status JobStore::apply(const std::vector<Event>& events) {
  if (events.empty()) return Status::Ok();
  if (Status s = exec("BEGIN IMMEDIATE"); !s.ok()) return s;
  job_totals_.clear();
  for (const Event& e : events) {
    if (Status s = apply_one(e); !s.ok()) {
      exec("ROLLBACK");
      return s;
    }
  }
  if (Status s = write_job_totals(); !s.ok()) {
    exec("ROLLBACK");
    return s;
  }
  if (Status s = exec("COMMIT"); !s.ok()) {
    exec("ROLLBACK");
    return s;
  }
  return Status::Ok();
}

Status JobStore::apply_one(const Event& e) {
  const double now = wall_now();
  if (const auto* a = std::get_if<event::JobAdded>(&e)) {
    const JobRecord& r = a->job;
    const JobSpec& s = r.spec;
    Statement ins(*this,
                  "INSERT INTO jobs(seq, id, request_id, fingerprint, scene_hash, scene_name, "
                  "width, height, frame_first, frame_last, bands, output, orbit, method, boxes, "
                  "spp, state, submitted_at, aa, tess_tol, band_edges, priority, frame_order, "
                  "band_timeout_ms, owner, require_tags, after_jobs, row_costs, kind, movie, fps, "
                  "notify_url) "
                  "VALUES(?,?,NULLIF(?, ''),?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
    ins.bind(r.seq, r.job_id, r.request_id, r.fingerprint, s.scene_hash, s.scene_name, s.width,
             s.height, s.frame_first, s.frame_last, s.bands, s.output, s.orbit_degrees,
             s.render.method, s.render.boxes, s.render.spp, job_state_name(JobState::kQueued), now,
             s.render.aa, s.render.tess_tol, band_edges_text(s.band_edges), s.priority,
             std::string(label_name(kFrameOrderLabels, s.frame_order)),
             static_cast<int64_t>(s.band_timeout.count()), s.owner, words_text(s.require),
             words_text(s.after), costs_text(s.row_costs),
             std::string(label_name(kJobKindLabels, s.kind)), s.movie, s.fps, s.notify_url);
    if (Status st = ins.run(); !st.ok()) return st;
    if (s.kind == JobKind::kMovie) {
      return add_history(r.job_id, -1, -1,
                         fmt::format("submitted{}: the movie {} of job {} at {} fps",
                                     s.owner.empty() ? "" : " by " + s.owner, s.output,
                                     s.after.empty() ? "?" : s.after.front(), s.fps));
    }
    return add_history(
        r.job_id, -1, -1,
        fmt::format("submitted{}: {} at {}x{}, frames {}-{}, {} bands per frame, "
                    "priority {}{}",
                    s.owner.empty() ? "" : " by " + s.owner, s.scene_name, s.width, s.height,
                    s.frame_first, s.frame_last, s.bands, s.priority,
                    s.frame_order == FrameOrder::kInOrder ? "" : ", frames first-middle-last"));
  }
  if (const auto* c = std::get_if<event::JobStateChanged>(&e)) {
    Statement st(*this,
                 "UPDATE jobs SET state = ?, error = ?, finished_at = CASE WHEN ? THEN ? ELSE NULL "
                 "END WHERE id = ?");
    st.bind(job_state_name(c->state), c->error, is_terminal(c->state), now, c->job_id);
    if (Status s = st.run(); !s.ok()) return s;
    return add_history(c->job_id, -1, -1,
                       std::string("state ") + job_state_name(c->state) +
                           (c->error.empty() ? "" : ": " + c->error));
  }
  if (const auto* g = std::get_if<event::LeaseGranted>(&e)) {
    // Its history line is made from this row when read (history()).
    Statement n(*this, "SELECT COUNT(*) FROM attempts WHERE job_id = ? AND frame = ? AND band = ?");
    n.bind(g->job_id, g->frame, g->band);
    const int64_t attempt = (n.step() == SQLITE_ROW ? n.integer(0) : 0) + 1;
    Statement st(*this,
                 "INSERT INTO attempts(lease_id, job_id, frame, band, worker_id, worker_name, "
                 "speculative, started_at, grant_seq, attempt) VALUES(?,?,?,?,?,?,?,?,?,?)");
    st.bind(g->lease_id, g->job_id, g->frame, g->band, g->worker_id, g->worker_name, g->speculative,
            g->granted_at > 0 ? g->granted_at : now, next_seq_++, attempt);
    return st.run();
  }
  if (const auto* l = std::get_if<event::LeaseEnded>(&e)) {
    Statement st(*this,
                 "UPDATE attempts SET ended_at = ?, outcome = ?, error = ?, charged = ?, "
                 "end_seq = ?, requeued = ? WHERE lease_id = ? AND outcome IS NULL");
    st.bind(now, lease_outcome_name(l->outcome), l->error, is_charged(l->outcome), next_seq_++,
            l->requeued, l->lease_id);
    if (Status s = st.run(); !s.ok()) return s;
    job_totals_[l->job_id].failed_lost = {l->job_account.failed, l->job_account.lost};
    if (!is_charged(l->outcome)) return Status::Ok();
    Statement band(*this,
                   "INSERT INTO bands(job_id, frame, band, failures, last_error) VALUES(?,?,?,1,?) "
                   "ON CONFLICT(job_id, frame, band) DO UPDATE SET failures = failures + 1, "
                   "last_error = excluded.last_error");
    band.bind(l->job_id, l->frame, l->band, l->error);
    return band.run();
  }
  if (const auto* d = std::get_if<event::BandDone>(&e)) {
    Statement band(*this,
                   "INSERT INTO bands(job_id, frame, band, done, completions, lease_id, worker_id, "
                   "stats) VALUES(?,?,?,1,1,?,?,?) ON CONFLICT(job_id, frame, band) DO UPDATE SET "
                   "done = 1, completions = completions + 1, lease_id = excluded.lease_id, "
                   "worker_id = excluded.worker_id, stats = excluded.stats");
    band.bind(d->job_id, d->frame, d->band, d->lease_id, d->worker_id,
              encode_stats(d->band_stats));
    if (Status s = band.run(); !s.ok()) return s;
    Statement attempt(*this,
                      "UPDATE attempts SET ended_at = ?, outcome = 'done', end_seq = ?, seconds = ? "
                      "WHERE lease_id = ? AND outcome IS NULL");
    attempt.bind(now, next_seq_++, d->seconds, d->lease_id);
    if (Status s = attempt.run(); !s.ok()) return s;
    // The pixels in the same transaction as "done": never one without the other.
    if (!d->pixels.empty()) {
      Statement px(*this,
                   "INSERT OR REPLACE INTO band_pixels(job_id, frame, band, pixels) "
                   "VALUES(?,?,?,?)");
      px.bind(d->job_id, d->frame, d->band, Blob{d->pixels});
      if (Status s = px.run(); !s.ok()) return s;
    }
    job_totals_[d->job_id].stats = {encode_stats(d->job_stats), d->job_account.done};
    return Status::Ok();
  }
  if (const auto* f = std::get_if<event::FrameWritten>(&e)) {
    Statement st(*this,
                 "INSERT OR REPLACE INTO frames(job_id, frame, file, written_at) VALUES(?,?,?,?)");
    st.bind(f->job_id, f->frame, f->file_name, now);
    if (Status s = st.run(); !s.ok()) return s;
    // The frame holds its bands' pixels now.
    Statement px(*this, "DELETE FROM band_pixels WHERE job_id = ? AND frame = ?");
    px.bind(f->job_id, f->frame);
    if (Status s = px.run(); !s.ok()) return s;
    return add_history(f->job_id, f->frame, -1,
                       fmt::format("frame {} written: {}", f->frame, f->file_name));
  }
  if (const auto* p = std::get_if<event::PriorityChanged>(&e)) {
    Statement st(*this, "UPDATE jobs SET priority = ? WHERE id = ?");
    st.bind(p->priority, p->job_id);
    return st.run();
  }
  if (const auto* r = std::get_if<event::JobReopened>(&e)) {
    Statement st(*this,
                 "UPDATE jobs SET state = ?, error = '', finished_at = NULL WHERE id = ?");
    st.bind(job_state_name(r->state), r->job_id);
    if (Status s = st.run(); !s.ok()) return s;
    for (int f : r->frames) {
      for (const char* sql :
           {"DELETE FROM frames WHERE job_id = ? AND frame = ?",
            "UPDATE bands SET done = 0, completions = 0 WHERE job_id = ? AND frame = ?"}) {
        Statement q(*this, sql);
        q.bind(r->job_id, f);
        if (Status s = q.run(); !s.ok()) return s;
      }
    }
    if (!r->fresh_attempts) return Status::Ok();
    for (const char* sql : {"UPDATE attempts SET charged = 0 WHERE job_id = ? AND charged = 1",
                            "UPDATE bands SET failures = 0 WHERE job_id = ?"}) {
      Statement q(*this, sql);
      q.bind(r->job_id);
      if (Status s = q.run(); !s.ok()) return s;
    }
    return Status::Ok();
  }
  if (const auto* n = std::get_if<event::JobNote>(&e))
    return add_history(n->job_id, -1, -1, n->text);
  if (const auto* n = std::get_if<event::JobNotified>(&e)) {
    if (n->phase != event::NotifyPhase::kNote) {
      Statement st(*this, "UPDATE jobs SET notify_pending = ? WHERE id = ?");
      st.bind(n->phase == event::NotifyPhase::kPending, n->job_id);
      if (Status s = st.run(); !s.ok()) return s;
    }
    return n->text.empty() ? Status::Ok() : add_history(n->job_id, -1, -1, n->text);
  }
  if (const auto* b = std::get_if<event::BandLog>(&e)) {
    for (const std::string& line : b->lines) {
      Statement st(*this,
                   "INSERT INTO band_logs(job_id, frame, band, lease_id, worker_id, text) "
                   "VALUES(?,?,?,?,?,?)");
      st.bind(b->job_id, b->frame, b->band, b->lease_id, b->worker_id, line);
      if (Status s = st.run(); !s.ok()) return s;
    }
    return Status::Ok();
  }
  if (const auto* d = std::get_if<event::WorkerDisabled>(&e)) {
    Statement st(*this, d->disabled ? "INSERT OR IGNORE INTO disabled_workers(name) VALUES(?)"
                                    : "DELETE FROM disabled_workers WHERE name = ?");
    st.bind(d->name);
    return st.run();
  }
  if (const auto* w = std::get_if<event::WorkerAdded>(&e)) {
    Statement st(*this, "INSERT OR REPLACE INTO meta(key, value) VALUES('next_worker', ?)");
    st.bind(std::to_string(w->next_worker));
    return st.run();
  }
  return Status::Ok();
}

Status JobStore::write_job_totals() {
  for (const auto& [job_id, t] : job_totals_) {
    if (t.stats) {
      Statement st(*this, "UPDATE jobs SET stats = ?, band_seconds = ? WHERE id = ?");
      st.bind(t.stats->first, t.stats->second, job_id);
      if (Status s = st.run(); !s.ok()) return s;
    }
    if (t.failed_lost) {
      Statement st(*this,
                   "UPDATE jobs SET band_seconds_failed = ?, band_seconds_lost = ? WHERE id = ?");
      st.bind(t.failed_lost->first, t.failed_lost->second, job_id);
      if (Status s = st.run(); !s.ok()) return s;
    }
  }
  job_totals_.clear();
  return Status::Ok();
}

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

Result<RecoveredState> JobStore::recover() {
  RecoveredState state;
  const double now = wall_now();
  {
    // Each lease of the previous run ends in the job's history too, in one
    // transaction with its outcome.
    if (Status s = exec("BEGIN IMMEDIATE"); !s.ok()) return s;
    struct Open {
      std::string lease, job;
      int frame, band;
    };
    std::vector<Open> open;
    {
      Statement st(*this, "SELECT lease_id, job_id, frame, band FROM attempts WHERE outcome IS NULL");
      while (st.step() == SQLITE_ROW) {
        open.push_back({st.text(0), st.text(1), static_cast<int>(st.integer(2)),
                        static_cast<int>(st.integer(3))});
      }
    }
    Status s = Status::Ok();
    for (size_t i = 0; s.ok() && i < open.size(); ++i) {
      Statement st(*this,
                   "UPDATE attempts SET ended_at = ?, outcome = 'void', "
                   "error = 'the coordinator restarted', end_seq = ?, requeued = 1 "
                   "WHERE lease_id = ?");
      st.bind(now, next_seq_++, open[i].lease);
      s = st.run();
    }
    if (s.ok()) s = exec("COMMIT");
    if (!s.ok()) {
      exec("ROLLBACK");
      return s;
    }
    state.leases_voided = static_cast<int64_t>(open.size());
  }
  {
    Statement st(*this, "SELECT value FROM meta WHERE key = 'next_worker'");
    if (st.step() == SQLITE_ROW) state.next_worker = std::stoull("0" + st.text(0));
    if (state.next_worker == 0) state.next_worker = 1;
  }
  {
    Statement st(*this, "SELECT name FROM disabled_workers ORDER BY name");
    while (st.step() == SQLITE_ROW) state.disabled_workers.push_back(st.text(0));
  }
  Statement jobs(
      *this,
      "SELECT seq, id, COALESCE(request_id, ''), fingerprint, scene_hash, scene_name, "
      "width, height, frame_first, frame_last, bands, output, orbit, method, boxes, spp, "
      "state, error, submitted_at, finished_at, stats, aa, tess_tol, band_edges, priority, "
      "frame_order, band_timeout_ms, owner, require_tags, after_jobs, band_seconds, "
      "band_seconds_failed, band_seconds_lost, row_costs, kind, movie, fps, notify_url, notify_pending "
      "FROM jobs ORDER BY seq");
  for (;;) {
    const int rc = jobs.step();
    if (rc == SQLITE_DONE) break;
    if (rc != SQLITE_ROW) return jobs.error();
    RecoveredJob j;
    JobRecord& r = j.record;
    r.seq = jobs.integer(0);
    r.job_id = jobs.text(1);
    r.request_id = jobs.text(2);
    r.fingerprint = jobs.text(3);
    JobSpec& s = r.spec;
    s.scene_hash = jobs.text(4);
    s.scene_name = jobs.text(5);
    s.width = static_cast<int>(jobs.integer(6));
    s.height = static_cast<int>(jobs.integer(7));
    s.frame_first = static_cast<int>(jobs.integer(8));
    s.frame_last = static_cast<int>(jobs.integer(9));
    s.bands = static_cast<int>(jobs.integer(10));
    s.output = jobs.text(11);
    s.orbit_degrees = jobs.real(12);
    s.render.method = jobs.text(13);
    s.render.boxes = jobs.text(14);
    s.render.spp = static_cast<int>(jobs.integer(15));
    {
      auto edges = band_edges_from_text(jobs.text(23), s.height, s.bands);
      if (!edges.ok()) {
        std::string why = "job store: job ";
        why.append(r.job_id).append(": ").append(edges.status().message());
        return Internal(why);
      }
      s.band_edges = std::move(*edges);
    }
    j.state = state_from_name(jobs.text(16));
    j.error = jobs.text(17);
    const double submitted = jobs.real(18);
    j.seconds_elapsed = (jobs.null(19) ? now : jobs.real(19)) - submitted;
    j.stats = decode_stats(jobs.text(20));
    s.render.aa = static_cast<int>(jobs.integer(21));
    s.render.tess_tol = jobs.real(22);
    s.priority = std::clamp(static_cast<int>(jobs.integer(24)), kMinPriority, kMaxPriority);
    s.frame_order = label_value(kFrameOrderLabels, jobs.text(25)).value_or(FrameOrder::kInOrder);
    s.band_timeout = Millis(std::max<int64_t>(0, jobs.integer(26)));
    s.owner = jobs.text(27);
    s.require = words_from_text(jobs.text(28));
    s.after = words_from_text(jobs.text(29));
    j.account = {jobs.real(30), jobs.real(31), jobs.real(32)};
    s.row_costs = costs_from_text(jobs.text(33));
    if (static_cast<int>(s.row_costs.size()) != s.height) s.row_costs.clear();
    s.kind = label_value(kJobKindLabels, jobs.text(34)).value_or(JobKind::kRender);
    s.movie = jobs.text(35);
    s.fps = static_cast<int>(jobs.integer(36));
    s.notify_url = jobs.text(37);
    j.notify_pending = jobs.integer(38) != 0;
    state.jobs.push_back(std::move(j));
  }
  for (RecoveredJob& j : state.jobs) {
    const std::string& id = j.record.job_id;
    {
      Statement st(*this, "SELECT frame FROM frames WHERE job_id = ? ORDER BY frame");
      st.bind(id);
      while (st.step() == SQLITE_ROW) j.frames_written.push_back(static_cast<int>(st.integer(0)));
    }
    {
      Statement st(*this,
                   "SELECT SUM(outcome = 'discarded'), SUM(speculative) FROM attempts "
                   "WHERE job_id = ?");
      st.bind(id);
      if (st.step() == SQLITE_ROW) {
        j.results_discarded = st.integer(0);
        j.speculative_leases = st.integer(1);
      }
    }
    if (j.state == JobState::kSucceeded) {
      Statement st(*this, "SELECT COUNT(*) FROM bands WHERE job_id = ? AND done = 1");
      st.bind(id);
      if (st.step() == SQLITE_ROW) j.bands_done = st.integer(0);
      continue;
    }
    {
      Statement st(*this, "SELECT frame, band FROM bands WHERE job_id = ? AND done = 1");
      st.bind(id);
      while (st.step() == SQLITE_ROW) {
        j.done_bands.push_back({static_cast<int>(st.integer(0)), static_cast<int>(st.integer(1))});
      }
      j.bands_done = static_cast<int64_t>(j.done_bands.size());
    }
    if (is_terminal(j.state)) continue;
    {
      Statement st(*this,
                   "SELECT frame, band, worker_name, error FROM attempts WHERE job_id = ? AND "
                   "charged = 1 ORDER BY started_at");
      st.bind(id);
      while (st.step() == SQLITE_ROW) {
        j.failures.push_back({static_cast<int>(st.integer(0)), static_cast<int>(st.integer(1)),
                              st.text(2), st.text(3)});
      }
    }
  }
  return state;
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
