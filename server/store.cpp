// The job store (store.h): its schema, opening it, and the coordinator's
// events applied to it. Recovery after a restart is store_recover.cpp; the
// reads of history, bands, scenes, logs and attempts are store_queries.cpp.
#include "server/store.h"

#include <fmt/format.h>
#include <sqlite3.h>

#include <cstdio>
#include <sstream>
#include <string_view>
#include <tuple>

#include "server/store_internal.h"
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

// The SQL below names these outcomes in its text; the table is the word's
// one home.
static_assert(label_name(kLeaseOutcomeLabels, LeaseOutcome::kDone) == "done");
static_assert(label_name(kLeaseOutcomeLabels, LeaseOutcome::kDiscarded) == "discarded");

}  // namespace

namespace store_detail {

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

}  // namespace store_detail

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

Result<std::unique_ptr<JobStore>> JobStore::open(const std::string& path, bool sync) {
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
  // do for the rest. Without `sync`, OFF: a checkpoint's two syncs were
  // most of storing a big scene (SPD tetra level 9's 20 MB: 150-175 ms
  // against 90-100 ms).
  if (Status s = store->exec("PRAGMA journal_mode=WAL"); !s.ok()) return s;
  if (Status s = store->exec(sync ? "PRAGMA synchronous=NORMAL" : "PRAGMA synchronous=OFF");
      !s.ok()) {
    return s;
  }
  // Deleted records are not overwritten with zeros (Debian builds SQLite
  // with SECURE_DELETE on): a written frame's band records, deleted with it,
  // would otherwise be written to the WAL a second time as zeros
  // (docs/farm.md "The job store").
  if (Status s = store->exec("PRAGMA secure_delete=OFF"); !s.ok()) return s;
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
        {"jobs", "cost_map", "cost_map TEXT NOT NULL DEFAULT ''"},
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
    Statement ins(
        *this,
        "INSERT INTO jobs(seq, id, request_id, fingerprint, scene_hash, scene_name, "
        "width, height, frame_first, frame_last, bands, output, orbit, method, boxes, "
        "spp, state, submitted_at, aa, tess_tol, band_edges, priority, frame_order, "
        "band_timeout_ms, owner, require_tags, after_jobs, row_costs, kind, movie, fps, "
        "notify_url, cost_map) "
        "VALUES(?,?,NULLIF(?, ''),?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
    ins.bind(r.seq, r.job_id, r.request_id, r.fingerprint, s.scene_hash, s.scene_name, s.width,
             s.height, s.frame_first, s.frame_last, s.bands, s.output, s.orbit_degrees,
             s.render.method, s.render.boxes, s.render.spp, job_state_name(JobState::kQueued), now,
             s.render.aa, s.render.tess_tol, band_edges_text(s.band_edges), s.priority,
             std::string(label_name(kFrameOrderLabels, s.frame_order)),
             static_cast<int64_t>(s.band_timeout.count()), s.owner, words_text(s.require),
             words_text(s.after), costs_text(s.row_costs),
             std::string(label_name(kJobKindLabels, s.kind)), s.movie, s.fps, s.notify_url,
             s.cost_map);
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

}  // namespace locus::farm
