// The Scheduler (scheduler.h): dispatch. Which band a worker gets next
// (priorities, dependencies, pools, quarantine, speculation), its lease,
// the band's result, and the leases that lapse.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/base/log.h"
#include "server/scheduler.h"
#include "server/scheduler_internal.h"

namespace locus::farm {
using scheduler_detail::format_seconds;
using scheduler_detail::seconds;

namespace {

constexpr size_t kDurationsKept = 64;  // per job, for the speculation threshold

// What is wrong with a result's pixels for a band of `width` x `rows`, or
// nothing: encoded pixels that did not decode (the coordinator's check,
// band_codec.h), of another size, or floats of another count.
std::string pixels_problem(const BandOutput& out, int width, int rows) {
  if (!out.malformed.empty()) return out.malformed;
  if (!out.encoded.bytes.empty()) {
    if (out.encoded.width == width && out.encoded.rows == rows) return "";
    return "expected " + std::to_string(width) + " x " + std::to_string(rows) + " pixels, got " +
           std::to_string(out.encoded.width) + " x " + std::to_string(out.encoded.rows);
  }
  const size_t expected = static_cast<size_t>(width) * rows * 3;
  if (out.rgb.size() == expected) return "";
  return "expected " + std::to_string(expected) + " floats (" + std::to_string(width) + " x " +
         std::to_string(rows) + " x 3), got " + std::to_string(out.rgb.size());
}

}  // namespace

bool Scheduler::quarantined(const Job& job, const std::string& worker_name) const {
  if (options_.quarantine_after <= 0) return false;
  auto it = job.worker_failures.find(worker_name);
  return it != job.worker_failures.end() && it->second >= options_.quarantine_after;
}

bool Scheduler::another_worker_for(const Job& job, int job_band,
                                   const std::string& worker_name) const {
  const Failures* f = nullptr;
  if (job_band >= 0) {
    auto it = job.failures.find(job_band);
    if (it != job.failures.end()) f = &it->second;
  }
  for (const auto& [id, w] : workers_) {
    if (w.info.name == worker_name || quarantined(job, w.info.name)) continue;
    if (f && f->workers.count(w.info.name)) continue;
    return true;
  }
  return false;
}

int Scheduler::pick_band(Job& job, const std::string& worker_name) {
  // Bands back in the queue first, each on a worker it has not failed on
  // where another can take it.
  for (auto it = job.retry.begin(); it != job.retry.end(); ++it) {
    const int i = *it;
    auto f = job.failures.find(i);
    if (f == job.failures.end() || !f->second.workers.count(worker_name) ||
        !another_worker_for(job, i, worker_name)) {
      job.retry.erase(it);
      return i;
    }
  }
  if (job.next_fresh < static_cast<int>(job.bands.size())) return fresh_band(job, job.next_fresh++);
  return -1;
}

int Scheduler::fresh_band(const Job& job, int position) {
  const JobSpec& s = job.info.spec;
  if (s.frame_order == FrameOrder::kInOrder) return position;
  // First, middle, last (distinct; frame indices from 0), then the others
  // in order: the p-th other frame is p plus the special frames at or
  // below it.
  const int n = s.frames();
  int special[3] = {0, (n - 1) / 2, n - 1};
  int count = 1;
  for (int k = 1; k < 3; ++k) {
    if (special[k] != special[count - 1]) special[count++] = special[k];
  }
  const int p = position / s.bands;
  int frame = p;
  if (p < count) {
    frame = special[p];
  } else {
    frame = p - count;
    for (int k = 0; k < count; ++k) {
      if (frame >= special[k]) ++frame;
    }
  }
  return frame * s.bands + position % s.bands;
}

double Scheduler::effective_priority(const Job& job, TimePoint now) const {
  double p = job.info.spec.priority;
  if (options_.ageing.count() > 0) {
    p += std::floor(seconds(now - job.waiting_since) /
                    std::chrono::duration<double>(options_.ageing).count());
  }
  return p;
}

bool Scheduler::carries(const WorkerInfo& worker, const Job& job) {
  for (const std::string& t : job.info.spec.require) {
    if (std::find(worker.tags.begin(), worker.tags.end(), t) == worker.tags.end()) return false;
  }
  return true;
}

const Scheduler::Job* Scheduler::waiting_for(const Job& job) const {
  for (const std::string& id : job.info.spec.after) {
    const Job* before = find_job(id);
    if (before && before->info.state != JobState::kSucceeded) return before;
  }
  return nullptr;
}

Status Scheduler::check_after(const std::vector<std::string>& after) const {
  for (const std::string& id : after) {
    const Job* before = find_job(id);
    if (!before) {
      return InvalidArgument("after " + id.substr(0, 64) +
                             ": no such job; `locus status` lists the jobs");
    }
    const JobState st = before->info.state;
    if (st == JobState::kFailed || st == JobState::kCancelled) {
      return InvalidArgument("after " + id + ": that job " + job_state_name(st) +
                             ", so this one could never start");
    }
  }
  return Status::Ok();
}

void Scheduler::fail_dependents(const Job& job) {
  const std::string why = "job " + job.info.job_id + ", which it waits for (--after), " +
                          job_state_name(job.info.state);
  std::vector<Job*> dependents;
  for (auto& [id, j] : jobs_) {
    if (is_terminal(j.info.state)) continue;
    const auto& after = j.info.spec.after;
    if (std::find(after.begin(), after.end(), job.info.job_id) != after.end())
      dependents.push_back(&j);
  }
  for (Job* j : dependents) end_job(*j, JobState::kFailed, why);
}

Scheduler::Job* Scheduler::best_job(const WorkerInfo& worker,
                                    const std::vector<const Job*>& passed) {
  const std::string& worker_name = worker.name;
  struct Key {
    double priority;
    int user_running;
    int job_running;
    int64_t seq;
    bool before(const Key& o) const {
      if (priority != o.priority) return priority > o.priority;
      if (user_running != o.user_running) return user_running < o.user_running;
      if (job_running != o.job_running) return job_running < o.job_running;
      return seq < o.seq;
    }
  };
  const TimePoint now = now_();
  Job* best = nullptr;
  Key best_key{};
  for (auto& [seq, live] : live_) {
    Job& job = *live;
    const JobState st = job.info.state;
    if (st == JobState::kPaused || !queued(job)) continue;
    if (std::find(passed.begin(), passed.end(), &job) != passed.end()) continue;
    if (!carries(worker, job) || waiting_for(job)) continue;
    // Quarantine holds only while another worker can take the job's bands:
    // a farm of one keeps going, bounded by the attempt limit.
    if (quarantined(job, worker_name) && another_worker_for(job, -1, worker_name)) continue;
    auto u = user_running_.find(job.info.spec.owner);
    const int user = u == user_running_.end() ? 0 : u->second;
    if (options_.user_max_running > 0 && user >= options_.user_max_running) continue;
    const Key key{effective_priority(job, now), user, job.running, job.record.seq};
    if (!best || key.before(best_key)) {
      best = &job;
      best_key = key;
    }
  }
  return best;
}

double Scheduler::speculate_after(const Job& job) const {
  // "Far longer than its peers": a multiple of the median of the job's
  // finished bands; no peers yet, no speculation.
  if (options_.speculate_factor <= 0 || job.durations.size() < 3) return -1;
  std::vector<double> d(job.durations.begin(), job.durations.end());
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return std::max(options_.speculate_factor * d[d.size() / 2],
                  std::chrono::duration<double>(options_.speculate_min).count());
}

const std::string* Scheduler::speculation_candidate(const WorkerInfo& worker) const {
  if (options_.speculate_factor <= 0) return nullptr;
  const std::string& worker_name = worker.name;
  const TimePoint now = now_();
  // The lease running longest relative to its job's threshold (ratio > 1),
  // the lowest lease id among equals. In each job only its oldest leases
  // can be that: the walk stops at the first one younger than the best.
  const std::string* best = nullptr;
  double best_ratio = 1.0;
  for (const auto& [seq, live] : live_) {
    const Job& job = *live;
    if (job.solo.empty() || job.info.state == JobState::kPaused ||
        quarantined(job, worker_name) || !carries(worker, job)) {
      continue;
    }
    const double after = speculate_after(job);
    if (after <= 0) continue;
    for (const auto& [granted, id] : job.solo) {
      const double ratio = seconds(now - granted) / after;
      if (ratio < best_ratio || (ratio == best_ratio && !best)) break;
      const Lease& l = leases_.at(id);
      if (l.worker_name == worker_name) continue;
      const BandState& state = job.bands[l.job_band];
      if (state.leases != 1 || state.speculated) continue;
      if (ratio > best_ratio || id < *best) {
        best_ratio = ratio;
        best = &id;
      }
    }
  }
  return best;
}

BandLease Scheduler::make_lease(const Job& job, int job_band, const Lease& lease,
                                const std::string& lease_id) const {
  const JobSpec& s = job.info.spec;
  BandLease out;
  out.lease_id = lease_id;
  out.lease_remaining = std::chrono::duration_cast<Millis>(lease.deadline - now_());
  out.job_id = job.info.job_id;
  out.scene_hash = s.scene_hash;
  out.frame = frame_of(job, job_band);
  out.band = band_of(job, job_band);
  const Band rows = band_rows(s, out.band);
  out.y0 = rows.y0;
  out.y1 = rows.y1;
  out.width = s.width;
  out.height = s.height;
  out.render = s.render;
  out.orbit_degrees = s.orbit_degrees;
  out.frame_first = s.frame_first;
  out.frame_last = s.frame_last;
  const auto worker = workers_.find(lease.worker_id);
  const EncodingOffers offers =
      worker != workers_.end() ? worker->second.info.encodings : EncodingOffers{};
  out.encoding = band_encoding_for(
      s.output, offers.png_deflate,
      options_.exr_zip && offers.exr_zip && holds_exr_block(out.y0, out.y1, s.height));
  out.cost_map = !s.cost_map.empty();
  return out;
}

Result<std::optional<BandLease>> Scheduler::grant(Job& job, int job_band, Worker& worker,
                                                  bool speculative) {
  BandState& state = job.bands[job_band];
  state.phase = BandPhase::kLeased;
  ++state.leases;
  if (speculative) {
    state.speculated = 1;
    ++job.info.speculative_leases;
    BandLogScope log_scope(job.info.job_id, frame_of(job, job_band), band_of(job, job_band));
    spdlog::info("job {}: {} runs far longer than its peers; second lease to worker {}",
                 job.info.job_id, band_name(job, job_band), worker.info.worker_id);
  }
  const std::string id = lease_prefix_ + std::to_string(next_lease_++);
  const TimePoint now = now_();
  Lease lease{job.info.job_id,      job_band,   worker.info.worker_id, worker.info.name, now,
              now + options_.lease, speculative};
  leases_.emplace(id, lease);
  worker.leases.insert(id);
  if (!speculative && !state.speculated) job.solo.emplace(now, id);
  count_running(job, +1);
  job.waiting_since = now;
  if (job.info.state == JobState::kQueued) {
    job.info.state = JobState::kRunning;
    events_.push_back(event::JobStateChanged{job.info.job_id, JobState::kRunning, ""});
  }
  events_.push_back(event::LeaseGranted{id, job.info.job_id, frame_of(job, job_band),
                                        band_of(job, job_band), worker.info.worker_id,
                                        worker.info.name, speculative, wall_now()});
  ++version_;
  return std::optional<BandLease>(make_lease(job, job_band, lease, id));
}

Result<std::optional<BandLease>> Scheduler::next_band(const std::string& worker_id) {
  const Status alive = touch(worker_id);
  if (!alive.ok()) return alive;
  Worker& worker = workers_.at(worker_id);
  const std::string& name = worker.info.name;
  // A drained or disabled worker gets nothing, not even a speculative copy.
  if (worker.info.draining || worker.info.disabled) return std::optional<BandLease>();
  // One pass over the jobs for the best; another only when its queued
  // bands all wait for other workers (pick_band: none for this one).
  std::vector<const Job*> passed;
  while (Job* job = best_job(worker.info, passed)) {
    const int job_band = pick_band(*job, name);
    if (job_band >= 0) return grant(*job, job_band, worker, false);
    passed.push_back(job);
  }
  if (const std::string* id = speculation_candidate(worker.info)) {
    const Lease& l = leases_.at(*id);
    Job& job = jobs_.at(l.job_id);
    job.solo.erase({l.granted, *id});  // its band gets no third lease
    return grant(job, l.job_band, worker, true);
  }
  return std::optional<BandLease>();
}

Result<std::vector<std::string>> Scheduler::heartbeat(const std::string& worker_id,
                                                      const std::vector<std::string>& lease_ids) {
  const Status alive = touch(worker_id);
  if (!alive.ok()) return alive;
  std::vector<std::string> revoked;
  const TimePoint now = now_();
  for (const std::string& id : lease_ids) {
    auto it = leases_.find(id);
    if (it == leases_.end() || it->second.worker_id != worker_id || it->second.deadline < now) {
      revoked.push_back(id);
      continue;
    }
    it->second.deadline = now + options_.lease;
  }
  return revoked;
}

void Scheduler::release(const std::string& lease_id, LeaseOutcome outcome, const std::string& why) {
  auto it = leases_.find(lease_id);
  if (it == leases_.end()) return;
  const Lease lease = it->second;
  leases_.erase(it);
  Job* job = find_job(lease.job_id);
  forget_lease(job, lease_id, lease);
  if (!job) return;
  count_running(*job, -1);
  if (outcome == LeaseOutcome::kTimedOut) ++job->info.bands_timed_out;
  const int frame = frame_of(*job, lease.job_band);
  const int band = band_of(*job, lease.job_band);
  BandLogScope log_scope(lease.job_id, frame, band);
  event::LeaseEnded ended{lease_id, lease.job_id, frame, band, outcome, why, false, 0, "", {}};
  account(*job, ended, lease);
  ++version_;
  if (is_terminal(job->info.state)) {
    events_.push_back(std::move(ended));
    return;
  }
  BandState& state = job->bands[lease.job_band];
  if (state.leases > 0) --state.leases;
  if (outcome == LeaseOutcome::kDiscarded) ++job->info.results_discarded;
  if (is_charged(outcome)) {
    if (state.failures < 255) ++state.failures;
    Failures& f = job->failures[lease.job_band];
    f.workers.insert(lease.worker_name);
    f.last_error = why;
    const int n = ++job->worker_failures[lease.worker_name];
    if (options_.quarantine_after > 0 && n == options_.quarantine_after) {
      job->info.quarantined.push_back(lease.worker_name);
      spdlog::warn("job {}: worker {} ({}) failed {} times: quarantined for this job", lease.job_id,
                   lease.worker_id, lease.worker_name, n);
    }
  }
  // The band goes back to the queue unless it is done or its other lease
  // goes on; past the attempt limit its job fails instead.
  const bool free = state.phase != BandPhase::kDone && state.leases == 0;
  const bool failed = free && state.failures >= options_.max_attempts;
  ended.requeued = free && !failed;
  events_.push_back(std::move(ended));
  if (!free) return;
  state.phase = BandPhase::kQueued;
  if (failed) {
    end_job(*job, JobState::kFailed,
            band_name(*job, lease.job_band) + " failed " + std::to_string(state.failures) +
                " times; last: " + why);
    return;
  }
  spdlog::info("job {}: {} back in the queue: {}", lease.job_id, band_name(*job, lease.job_band),
               why);
  job->retry.push_front(lease.job_band);
}

std::optional<BandTarget> Scheduler::result_target(const BandOutput& out) const {
  auto it = leases_.find(out.lease_id);
  if (it == leases_.end() || it->second.worker_id != out.worker_id) return std::nullopt;
  if (it->second.deadline < now_() || out.handed_back || !out.error.empty()) return std::nullopt;
  const Job& job = jobs_.at(it->second.job_id);
  const JobSpec& s = job.info.spec;
  const int band = band_of(job, it->second.job_band);
  const Band rows = band_rows(s, band);
  if (!pixels_problem(out, s.width, rows.y1 - rows.y0).empty()) return std::nullopt;
  return BandTarget{job.info.job_id, frame_of(job, it->second.job_band), band, s.width, rows.y0,
                    rows.y1};
}

Result<CompleteOutcome> Scheduler::complete_band(const BandOutput& out) {
  const Status alive = touch(out.worker_id);
  if (!alive.ok()) return alive;
  CompleteOutcome outcome;
  auto it = leases_.find(out.lease_id);
  if (it == leases_.end() || it->second.worker_id != out.worker_id) {
    outcome.reason = "lease '" + out.lease_id +
                     "' is not held by this worker (lapsed, re-leased, cancelled, or its band was "
                     "done by another worker)";
    return outcome;
  }
  const std::string who = "worker " + out.worker_id + " (" + it->second.worker_name + ")";
  if (it->second.deadline < now_()) {
    // Strict: once the deadline has passed the band may already be leased
    // elsewhere as far as any observer can tell; the first valid result wins.
    release(out.lease_id, LeaseOutcome::kLapsed, "lease of " + who + " lapsed");
    outcome.reason = "lease '" + out.lease_id + "' lapsed before the result arrived";
    return outcome;
  }
  const Lease lease = it->second;
  Job& job = jobs_.at(lease.job_id);
  const JobSpec& s = job.info.spec;
  if (!out.log_lines.empty() && !out.handed_back) {
    events_.push_back(event::BandLog{job.info.job_id, frame_of(job, lease.job_band),
                                     band_of(job, lease.job_band), out.lease_id, out.worker_id,
                                     out.log_lines});
  }
  if (out.handed_back) {
    release(out.lease_id, LeaseOutcome::kHandedBack, "handed back by " + who);
    outcome.accepted = true;
    outcome.reason = "handed back";
    return outcome;
  }
  if (!out.error.empty()) {
    release(out.lease_id, LeaseOutcome::kFailed, who + ": " + out.error);
    outcome.accepted = true;
    return outcome;
  }
  const int band = band_of(job, lease.job_band);
  const int frame = frame_of(job, lease.job_band);
  const Band rows = band_rows(s, band);
  const std::string malformed = pixels_problem(out, s.width, rows.y1 - rows.y0);
  if (!malformed.empty()) {
    const std::string why =
        "band " + std::to_string(band) + " of frame " + std::to_string(frame) + ": " + malformed;
    release(out.lease_id, LeaseOutcome::kMalformed, who + " sent malformed pixels: " + why);
    // The worker is told which of its leases was refused, and why.
    return InvalidArgument("lease '" + out.lease_id + "' of job " + lease.job_id + ": " + why);
  }

  leases_.erase(it);
  count_running(job, -1);
  job.solo.erase({lease.granted, out.lease_id});
  Worker& worker = workers_.at(out.worker_id);
  worker.leases.erase(out.lease_id);
  ++worker.info.bands_done;
  BandState& state = job.bands[lease.job_band];
  state.phase = BandPhase::kDone;
  if (state.leases > 0) --state.leases;
  ++job.info.bands_done;
  job.info.stats += out.stats;
  const double took = seconds(now_() - lease.granted);
  job.durations.push_back(took);
  if (job.durations.size() > kDurationsKept) job.durations.pop_front();
  job.info.account.done += took;
  events_.push_back(event::BandDone{job.info.job_id, frame, band, out.lease_id, out.worker_id,
                                    job.info.stats, took, job.info.spec.owner,
                                    out.stats.seconds_render_cpu, job.info.account, out.stats,
                                    /*pixels=*/{}});
  // The first result wins: the band's other lease (a speculative copy, or
  // the original it copied) is discarded, counted once here.
  if (state.leases > 0) {
    std::vector<std::string> others;
    for (const auto& [id, l] : leases_) {
      if (l.job_id == lease.job_id && l.job_band == lease.job_band) others.push_back(id);
    }
    for (const std::string& id : others) {
      release(id, LeaseOutcome::kDiscarded, "band done first by lease " + out.lease_id);
    }
  }
  outcome.accepted = true;
  if (++job.frame_bands[frame] == s.bands) {
    job.frame_bands.erase(frame);
    outcome.frame = frame_ready(job.info.job_id, s, frame);
  }
  ++version_;
  return outcome;
}

void Scheduler::expire() {
  const TimePoint now = now_();
  std::vector<std::string> gone;
  for (const auto& [id, w] : workers_) {
    if (now - w.last_seen > options_.worker_timeout) gone.push_back(id);
  }
  for (const std::string& id : gone) {
    const Worker& w = workers_.at(id);
    spdlog::warn("worker {} ({}) silent for {:.1f} s: dropped", id, w.info.name,
                 seconds(now - w.last_seen));
    const std::set<std::string> held = w.leases;
    const std::string who = "worker " + id + " (" + w.info.name + ") went silent";
    for (const std::string& l : held) release(l, LeaseOutcome::kSilent, who);
    workers_.erase(id);
    ++version_;
  }
  // A band leased longer than its timeout hangs, however alive its worker:
  // taken back (charged, as a failure of the band) and leased elsewhere;
  // the worker hears of it at its next heartbeat and abandons the render.
  // Otherwise a lease past its deadline lapses.
  struct Ending {
    std::string lease_id;
    LeaseOutcome outcome;
    std::string why;
  };
  std::vector<Ending> ending;
  for (const auto& [id, l] : leases_) {
    const JobSpec& spec = jobs_.at(l.job_id).info.spec;
    const Millis limit = spec.band_timeout.count() > 0 ? spec.band_timeout : options_.band_timeout;
    const bool hung = limit.count() > 0 && now - l.granted > limit;
    if (!hung && l.deadline >= now) continue;  // the common case: nothing to build
    const std::string who = "worker " + l.worker_id + " (" + l.worker_name + ")";
    if (hung) {
      ending.push_back({id, LeaseOutcome::kTimedOut,
                        "band hung: leased to " + who + " for " +
                            format_seconds(seconds(now - l.granted)) +
                            ", over the band timeout of " +
                            format_seconds(std::chrono::duration<double>(limit).count())});
    } else if (l.deadline < now) {
      ending.push_back({id, LeaseOutcome::kLapsed, "lease of " + who + " lapsed"});
    }
  }
  for (const Ending& e : ending) {
    // An earlier release may have failed the job and dropped this lease.
    auto it = leases_.find(e.lease_id);
    if (it == leases_.end()) continue;
    if (e.outcome == LeaseOutcome::kTimedOut) {
      const Job& job = jobs_.at(it->second.job_id);
      BandLogScope log_scope(job.info.job_id, frame_of(job, it->second.job_band),
                             band_of(job, it->second.job_band));
      spdlog::warn("job {}: {}", job.info.job_id, e.why);
    }
    release(e.lease_id, e.outcome, e.why);
  }
}

}  // namespace locus::farm
