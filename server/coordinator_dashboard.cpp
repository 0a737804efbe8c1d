// The Coordinator's reads for the dashboard (server/http_api.h, and the
// GetFarm, GetFrame and GetWorker RPCs): the farm with a cursor, one
// frame's bands from the store, a worker's recent work, and the images'
// files. Its own file: they serve only pages, never dispatch.
#include <algorithm>
#include <filesystem>
#include <map>

#include "common/base/cost_map.h"
#include "server/band_files.h"
#include "server/coordinator.h"

namespace locus::farm {
namespace fs = std::filesystem;

Coordinator::Snapshot Coordinator::snapshot(uint64_t since, const Caller& caller) {
  std::lock_guard lk(mu_);
  Snapshot out;
  out.version = scheduler_.version();
  if (since != 0 && since == out.version) {
    out.unchanged = true;
    return out;
  }
  for (JobInfo& j : scheduler_.jobs()) {
    if (may_read(j, caller).ok()) out.jobs.push_back(std::move(j));
  }
  out.workers = scheduler_.workers();
  return out;
}

Result<FrameDetail> Coordinator::frame_detail(const std::string& job_id, int frame,
                                              const Caller& caller) {
  std::lock_guard lk(mu_);
  auto j = scheduler_.job(job_id);
  if (!j.ok()) return j.status();
  if (Status s = may_read(*j, caller); !s.ok()) return s;
  const JobSpec& s = j->spec;
  if (frame < s.frame_first || frame > s.frame_last) {
    return NotFound("frame " + std::to_string(frame) + ": job " + job_id + " has frames " +
                    std::to_string(s.frame_first) + "-" + std::to_string(s.frame_last));
  }
  if (!store_) return FailedPrecondition("the coordinator has no job store (not started)");
  auto attempts = store_->frame_attempts(job_id, frame);
  if (!attempts.ok()) return attempts.status();
  auto stats = store_->frame_band_stats(job_id, frame);
  if (!stats.ok()) return stats.status();
  FrameDetail d;
  d.job_id = job_id;
  d.frame = frame;
  d.width = s.width;
  d.height = s.height;
  d.written = std::find(j->frames_written.begin(), j->frames_written.end(), frame) !=
              j->frames_written.end();
  d.file_name = frame_path(s.output, frame);
  d.row_costs = s.row_costs;
  for (int b = 0; b < s.bands; ++b) {
    BandDetail band;
    band.band = b;
    const Band rows = band_rows(s, b);
    band.y0 = rows.y0;
    band.y1 = rows.y1;
    if (static_cast<int>(s.row_costs.size()) >= rows.y1) {
      for (int y = rows.y0; y < rows.y1; ++y) band.predicted_cost += s.row_costs[y];
    }
    d.bands.push_back(std::move(band));
  }
  for (AttemptInfo& a : *attempts) {
    if (a.band < 0 || a.band >= s.bands) continue;
    d.bands[a.band].attempts.push_back(std::move(a));
  }
  for (BandDetail& band : d.bands) {
    auto done = stats->find(band.band);
    band.state = done != stats->end() || d.written ? "done" : "queued";
    if (done != stats->end()) band.stats = done->second;
    // The accepted result is the latest `done` attempt; a live lease is
    // one without an outcome.
    for (auto a = band.attempts.rbegin(); a != band.attempts.rend(); ++a) {
      if (band.state == "done" && a->outcome == "done") {
        band.seconds = a->ended_at - a->started_at;
        band.worker_id = a->worker_id;
        band.worker_name = a->worker_name;
        break;
      }
      if (band.state != "done" && a->outcome.empty()) {
        band.state = "running";
        band.worker_id = a->worker_id;
        band.worker_name = a->worker_name;
        break;
      }
    }
  }
  return d;
}

Result<std::string> Coordinator::frame_file(const std::string& job_id, int frame,
                                            const Caller& caller, bool cost_map) {
  std::lock_guard lk(mu_);
  auto j = scheduler_.job(job_id);
  if (!j.ok()) return j.status();
  if (Status s = may_read(*j, caller); !s.ok()) return s;
  if (std::find(j->frames_written.begin(), j->frames_written.end(), frame) ==
      j->frames_written.end()) {
    return NotFound("frame " + std::to_string(frame) + " of job " + job_id + " is not written");
  }
  if (cost_map && j->spec.cost_map.empty())
    return NotFound("job " + job_id + " makes no cost maps");
  return (fs::path(job_dir(job_id)) /
          frame_path(cost_map ? j->spec.cost_map : j->spec.output, frame))
      .string();
}

Result<Image> Coordinator::band_image(const std::string& job_id, int frame, int band,
                                      const Caller& caller) {
  BandPixels rows;
  {
    std::lock_guard lk(mu_);
    auto j = scheduler_.job(job_id);
    if (!j.ok()) return j.status();
    if (Status s = may_read(*j, caller); !s.ok()) return s;
    const JobSpec& s = j->spec;
    if (frame < s.frame_first || frame > s.frame_last || band < 0 || band >= s.bands) {
      return NotFound("band " + std::to_string(band) + " of frame " + std::to_string(frame) +
                      ": not in job " + job_id);
    }
    const Band b = band_rows(s, band);
    rows = BandPixels{s.width, b.y0, b.y1};
  }
  // Outside the lock, through the reader connection.
  auto record = read_band_record(job_id, frame, band);
  auto pixels =
      record.ok() ? unpack_band(*record, rows) : Result<std::vector<float>>(record.status());
  if (!pixels.ok()) {
    return NotFound("band " + std::to_string(band) + " of frame " + std::to_string(frame) +
                    " of job " + job_id + " has no pixels here (not done, or its frame is written)");
  }
  Image image(rows.width, rows.y1 - rows.y0);
  image.rgb = std::move(*pixels);
  return image;
}

Result<Image> Coordinator::partial_cost_map(const std::string& job_id, int frame, int* bands_in,
                                            const Caller& caller) {
  FrameReady f;
  {
    std::lock_guard lk(mu_);
    auto j = scheduler_.job(job_id);
    if (!j.ok()) return j.status();
    if (Status s = may_read(*j, caller); !s.ok()) return s;
    const JobSpec& s = j->spec;
    if (s.cost_map.empty()) return NotFound("job " + job_id + " makes no cost maps");
    if (frame < s.frame_first || frame > s.frame_last) {
      return NotFound("frame " + std::to_string(frame) + ": job " + job_id + " has frames " +
                      std::to_string(s.frame_first) + "-" + std::to_string(s.frame_last));
    }
    if (std::find(j->frames_written.begin(), j->frames_written.end(), frame) !=
        j->frames_written.end()) {
      return NotFound("frame " + std::to_string(frame) + " of job " + job_id +
                      " is written: its cost map is the written file");
    }
    f = frame_ready(job_id, s, frame);
  }
  // Outside the lock, through the reader connection: each band's record as
  // it stands (a band not done has none; a frame written meanwhile has
  // none either, and shows empty until the next look finds its file).
  std::string held;
  int in = 0;
  auto cost = stitch_cost(
      f,
      [&](int band) -> Result<std::string_view> {
        auto record = read_band_record(job_id, frame, band);
        if (!record.ok()) return record.status();
        held = std::move(*record);
        return std::string_view(held);
      },
      &in);
  if (!cost.ok()) return cost.status();
  if (bands_in) *bands_in = in;
  return cost_map_image(*cost);
}

Result<WorkerDetail> Coordinator::worker_detail(const std::string& worker, const Caller& caller) {
  constexpr int kKept = 200;
  std::lock_guard lk(mu_);
  WorkerDetail d;
  d.worker_id = worker;
  for (const WorkerInfo& w : scheduler_.workers()) {
    if (w.worker_id == worker || w.name == worker) {
      d.info = w;
      d.worker_id = w.worker_id;
    }
  }
  if (!store_) return FailedPrecondition("the coordinator has no job store (not started)");
  auto attempts = store_->worker_attempts(d.worker_id, kKept);
  if (!attempts.ok()) return attempts.status();
  auto logs = store_->worker_logs(d.worker_id, kKept);
  if (!logs.ok()) return logs.status();
  if (!d.info && attempts->empty()) {
    return NotFound("worker '" + worker.substr(0, 200) +
                    "' is neither connected nor in the job store; `locus workers` lists them");
  }
  // Only what the caller may read of each job (--private-jobs).
  std::map<std::string, bool> readable;
  const auto may = [&](const std::string& job_id) {
    auto it = readable.find(job_id);
    if (it != readable.end()) return it->second;
    auto j = scheduler_.job(job_id);
    return readable[job_id] = j.ok() && may_read(*j, caller).ok();
  };
  for (AttemptInfo& a : *attempts) {
    if (may(a.job_id)) d.attempts.push_back(std::move(a));
  }
  for (BandLogLine& l : *logs) {
    const auto lease = std::find_if(d.attempts.begin(), d.attempts.end(),
                                    [&](const AttemptInfo& a) { return a.lease_id == l.lease_id; });
    if (lease != d.attempts.end() || !options_.private_jobs) d.logs.push_back(std::move(l));
  }
  return d;
}

}  // namespace locus::farm
