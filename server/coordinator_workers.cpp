// Coordinator's side of the worker calls (docs/farm.md "Leases" and "The
// farm at scale"): registration, leases and the long polls that wait for
// them (a parked GetTask answered by the dispatch thread), scenes and
// heartbeats.
#include <spdlog/spdlog.h>

#include <algorithm>

#include "server/coordinator.h"

namespace locus::farm {

Result<Registration> Coordinator::register_worker(const std::string& name, int threads,
                                                  const std::vector<std::string>& tags,
                                                  EncodingOffers offers) {
  if (Status s = check_tags(tags, "tag"); !s.ok()) return s;
  std::lock_guard lk(mu_);
  Registration r;
  r.worker_id = scheduler_.add_worker(name.empty() ? "unnamed" : name.substr(0, 200),
                                      std::max(1, threads), tags, offers);
  r.heartbeat = options_.heartbeat;
  r.lease = options_.lease;
  persist();
  spdlog::info("worker {} registered: {} ({} threads{}{})", r.worker_id, name, threads,
               tags.empty() ? "" : ", tags ", words_text(tags));
  changed_.notify_all();
  return r;
}

std::optional<Coordinator::PollAnswer> Coordinator::try_lease(const std::string& worker_id) {
  // A worker polling a coordinator that is going away waits elsewhere (its
  // retry backoff) rather than here.
  if (closing_) return PollAnswer(Status(Code::kUnavailable, "the coordinator is shutting down"));
  if (stopping_) return PollAnswer(std::optional<BandLease>());
  // No space to store what it would bring: the poll waits.
  if (!storage_trouble_.ok()) return std::nullopt;
  // Draining: no new leases; the poll waits out its time as on an idle farm
  // (the worker still counts as seen).
  PollAnswer r = std::optional<BandLease>();
  if (!draining_) {
    r = scheduler_.next_band(worker_id);
  } else if (Status alive = scheduler_.touch(worker_id); !alive.ok()) {
    r = alive;
  }
  if (!r.ok() || r->has_value()) return r;
  // A drained worker hears of it now (GetTaskResponse.drain), not at the
  // poll's end.
  if (scheduler_.draining(worker_id)) return r;
  return std::nullopt;
}

uint64_t Coordinator::poll_band(const std::string& worker_id, Millis wait, PollDone done) {
  const TimePoint since = SteadyClock::now();
  const TimePoint end = since + std::clamp(wait, Millis(0), options_.max_poll);
  std::unique_lock lk(mu_);
  std::optional<PollAnswer> now = try_lease(worker_id);
  if (!now && SteadyClock::now() >= end) now = PollAnswer(std::optional<BandLease>());
  if (now) {
    if (now->ok() && now->value().has_value()) {
      // The lease reaches the store with the next transaction (the next
      // batch, or the ticker's within a tick): a lease lost to a crash
      // only means the band is queued again, and a transaction per lease
      // was a third of the coordinator's work at a thousand workers.
      dispatch_.add(SteadyClock::now() - since);  // from the call to the lease
      changed_.notify_all();
    }
    lk.unlock();
    done(std::move(*now));
    return 0;
  }
  // Parked: dispatch_loop() answers it. Its end is seen within a tick.
  const uint64_t ticket = next_poll_++;
  polls_.emplace(ticket, Poll{worker_id, end, since, std::move(done)});
  poll_ends_.emplace(end, ticket);
  return ticket;
}

std::vector<BandLease> Coordinator::lease_more(const std::string& worker_id, int n) {
  std::vector<BandLease> out;
  if (n <= 0) return out;
  std::unique_lock lk(mu_);
  while (static_cast<int>(out.size()) < n) {
    std::optional<PollAnswer> a = try_lease(worker_id);
    if (!a || !a->ok() || !a->value().has_value()) break;
    out.push_back(std::move(*a->value()));
  }
  if (!out.empty()) changed_.notify_all();
  return out;
}

void Coordinator::cancel_poll(uint64_t ticket) {
  std::unique_lock lk(mu_);
  auto it = polls_.find(ticket);
  if (it == polls_.end()) return;
  PollDone done = std::move(it->second.done);
  poll_ends_.erase({it->second.end, ticket});
  polls_.erase(it);
  lk.unlock();
  done(std::optional<BandLease>());
}

Coordinator::PollAnswer Coordinator::lease_band(const std::string& worker_id, Millis wait,
                                                const CancelledFn& cancelled) {
  struct Answer {
    std::mutex mu;
    std::condition_variable cv;
    std::optional<PollAnswer> value;
  };
  auto answer = std::make_shared<Answer>();
  const uint64_t ticket = poll_band(worker_id, wait, [answer](PollAnswer a) {
    std::lock_guard lk(answer->mu);
    answer->value = std::move(a);
    answer->cv.notify_all();
  });
  std::unique_lock lk(answer->mu);
  while (!answer->cv.wait_for(lk, Millis(200), [&] { return answer->value.has_value(); })) {
    if (cancelled && cancelled()) {
      lk.unlock();
      cancel_poll(ticket);
      lk.lock();
    }
  }
  return std::move(*answer->value);
}

void Coordinator::serve_polls(bool all, std::vector<std::pair<PollDone, PollAnswer>>& answers) {
  if (polls_.empty()) return;
  // Oldest poll first. Only while bands are queued: an idle farm's parked
  // polls cost nothing per pass. Speculation (a second lease of a
  // straggler, Scheduler::next_band) needs no queued band; the oldest
  // poll asks for it once per tick.
  bool queued = scheduler_.has_queued_bands();
  int speculation = speculate_due_ ? 1 : 0;
  speculate_due_ = false;
  const TimePoint pass = SteadyClock::now();
  for (auto it = polls_.begin(); it != polls_.end();) {
    if (!all && !queued && speculation-- <= 0) break;
    std::optional<PollAnswer> a = try_lease(it->second.worker_id);
    if (!a) {
      ++it;
      continue;
    }
    if (a->ok() && a->value().has_value()) {
      // From the wake-up that found the band to the lease.
      dispatch_.add(SteadyClock::now() - std::max(pass, it->second.since));
      queued = scheduler_.has_queued_bands();
    }
    poll_ends_.erase({it->second.end, it->first});
    answers.emplace_back(std::move(it->second.done), std::move(*a));
    it = polls_.erase(it);
  }
}

void Coordinator::dispatch_loop() {
  std::unique_lock lk(mu_);
  uint64_t seen = scheduler_.version();
  TimePoint touched = SteadyClock::now();
  TimePoint ticked = touched;
  // A parked poll keeps its worker seen (Scheduler::expire drops workers
  // silent past the lease time), as the poll's own calls did.
  const Millis touch_every = std::clamp(options_.lease / 4, Millis(1), Millis(1000));
  for (;;) {
    const bool stop = stopping_;
    const bool all = stop || polls_all_ || closing_;
    polls_all_ = false;
    TimePoint now = SteadyClock::now();
    if (now - ticked >= options_.tick) {
      ticked = now;
      speculate_due_ = true;
    }
    std::vector<std::pair<PollDone, PollAnswer>> answers;
    if (all || speculate_due_ || scheduler_.version() != seen) serve_polls(all, answers);
    seen = scheduler_.version();
    now = SteadyClock::now();
    while (!poll_ends_.empty() && poll_ends_.begin()->first <= now) {
      auto it = polls_.find(poll_ends_.begin()->second);
      poll_ends_.erase(poll_ends_.begin());
      answers.emplace_back(std::move(it->second.done), std::optional<BandLease>());
      polls_.erase(it);
    }
    if (now - touched >= touch_every) {
      touched = now;
      for (const auto& [ticket, poll] : polls_) scheduler_.touch(poll.worker_id);
    }
    if (!answers.empty()) {
      lk.unlock();
      for (auto& [done, answer] : answers) done(std::move(answer));
      answers.clear();
      lk.lock();
      continue;
    }
    if (stop) return;
    TimePoint wake = ticked + options_.tick;
    if (!poll_ends_.empty()) wake = std::min(wake, poll_ends_.begin()->first);
    changed_.wait_until(lk, wake, [&] {
      return stopping_ || polls_all_ || (closing_ && !polls_.empty()) ||
             scheduler_.version() != seen;
    });
  }
}

Result<std::shared_ptr<const std::string>> Coordinator::get_scene(const std::string& worker_id,
                                                                  const std::string& hash) {
  std::lock_guard lk(mu_);
  const Status alive = scheduler_.touch(worker_id);
  if (!alive.ok()) return alive;
  auto it = scenes_.find(hash);
  if (it == scenes_.end()) return NotFound("scene " + hash + " is not held (its jobs are over)");
  return it->second;
}

Result<std::vector<std::string>> Coordinator::heartbeat(const std::string& worker_id,
                                                        const std::vector<std::string>& lease_ids) {
  std::lock_guard lk(mu_);
  return scheduler_.heartbeat(worker_id, lease_ids);
}

}  // namespace locus::farm
