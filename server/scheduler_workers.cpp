// The Scheduler (scheduler.h): its workers (registration, heartbeats,
// drain, disable) and the farm's counts.
#include <spdlog/spdlog.h>

#include "server/scheduler.h"
#include "server/scheduler_internal.h"

namespace locus::farm {
using scheduler_detail::numbered;
using scheduler_detail::seconds;

std::string Scheduler::add_worker(const std::string& name, int threads,
                                  const std::vector<std::string>& tags, EncodingOffers offers) {
  const std::string id = numbered("w", next_worker_++);
  Worker w;
  w.info.worker_id = id;
  w.info.name = name;
  w.info.threads = threads;
  w.info.tags = tags;
  w.info.encodings = offers;
  w.info.disabled = disabled_.count(name) > 0;
  w.last_seen = now_();
  workers_.emplace(id, std::move(w));
  events_.push_back(event::WorkerAdded{next_worker_});
  ++version_;
  return id;
}

Status Scheduler::touch(const std::string& worker_id) {
  auto it = workers_.find(worker_id);
  if (it == workers_.end()) {
    return NotFound(
        "worker '" + worker_id +
        "' is unknown (dropped after silence, or the coordinator restarted); register again");
  }
  it->second.last_seen = now_();
  return Status::Ok();
}

std::vector<WorkerInfo> Scheduler::workers() const {
  std::vector<WorkerInfo> out;
  const TimePoint now = now_();
  for (const auto& [id, w] : workers_) {
    WorkerInfo info = w.info;
    info.busy = !w.leases.empty();
    if (info.busy) {
      const Lease& l = leases_.at(*w.leases.begin());
      const Job& job = jobs_.at(l.job_id);
      info.job_id = l.job_id;
      info.frame = frame_of(job, l.job_band);
      info.band = band_of(job, l.job_band);
    }
    info.seconds_since_seen = seconds(now - w.last_seen);
    out.push_back(std::move(info));
  }
  return out;
}

Result<WorkerInfo> Scheduler::drain_worker(const std::string& worker) {
  for (auto& [id, w] : workers_) {
    if (id != worker && w.info.name != worker) continue;
    if (!w.info.draining) spdlog::info("worker {} ({}): draining", id, w.info.name);
    w.info.draining = true;
    ++version_;
    WorkerInfo info = w.info;
    info.busy = !w.leases.empty();
    return info;
  }
  return NotFound("worker '" + worker.substr(0, 200) +
                  "' is not connected; `locus workers` lists the workers");
}

Result<std::string> Scheduler::set_disabled(const std::string& worker, bool disabled) {
  std::string name = disabled_.count(worker) ? worker : "";
  for (const auto& [id, w] : workers_) {
    if (id == worker || w.info.name == worker) name = w.info.name;
  }
  if (name.empty()) {
    return NotFound("worker '" + worker.substr(0, 200) + "' is not connected" +
                    (disabled ? "" : " nor disabled") + "; `locus workers` lists the workers");
  }
  if (disabled ? disabled_.insert(name).second : disabled_.erase(name) > 0) {
    events_.push_back(event::WorkerDisabled{name, disabled});
    spdlog::info("worker {}: {}", name, disabled ? "disabled" : "enabled");
  }
  for (auto& [id, w] : workers_) {
    if (w.info.name == name) w.info.disabled = disabled;
  }
  ++version_;
  return name;
}

bool Scheduler::draining(const std::string& worker_id) const {
  auto it = workers_.find(worker_id);
  return it != workers_.end() && it->second.info.draining;
}

std::set<std::string> Scheduler::scenes_in_use() const {
  std::set<std::string> used;
  for (const auto& [seq, job] : live_) used.insert(job->info.spec.scene_hash);
  return used;
}

std::set<std::string> Scheduler::scenes_kept() const {
  std::set<std::string> kept;
  for (const auto& [id, job] : jobs_) kept.insert(job.info.spec.scene_hash);
  return kept;
}

size_t Scheduler::unfinished_jobs() const {
  return live_.size();
}

FarmCounts Scheduler::counts() const {
  FarmCounts c;
  for (const auto& [id, job] : jobs_) {
    ++c.jobs[static_cast<size_t>(job.info.state)];
    c.bands_done += job.info.bands_done;
    if (is_terminal(job.info.state)) continue;
    c.bands_queued += static_cast<int64_t>(job.retry.size()) +
                      static_cast<int64_t>(job.bands.size()) - job.next_fresh;
  }
  std::set<std::pair<std::string, int>> running;  // a band with two leases is one band
  for (const auto& [id, l] : leases_) running.emplace(l.job_id, l.job_band);
  c.bands_running = static_cast<int64_t>(running.size());
  c.workers = static_cast<int64_t>(workers_.size());
  return c;
}

bool Scheduler::has_queued_bands() const {
  for (const auto& [seq, job] : live_) {
    if (job->info.state != JobState::kPaused && queued(*job)) return true;
  }
  return false;
}

}  // namespace locus::farm
