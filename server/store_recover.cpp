// The job store (store.h): what a restarted coordinator reads back
// (JobStore::recover).
#include <sqlite3.h>

#include <sstream>
#include <string>
#include <vector>

#include "server/store.h"
#include "server/store_internal.h"

namespace locus::farm {
namespace {

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

}  // namespace

using store_detail::decode_stats;

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
      "band_seconds_failed, band_seconds_lost, row_costs, kind, movie, fps, notify_url, "
      "notify_pending, cost_map "
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
    s.cost_map = jobs.text(39);
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

}  // namespace locus::farm
