// Coordinator's results and their durability (docs/farm.md "Durability:
// the group commit" and "A full disk"): a band's result checked and
// accepted, its record and its "done" stored in one transaction with the
// rest of its batch, one sync of the store's log per batch, then the
// acknowledgement; and what happens when the data directory cannot be
// written: the events kept in memory, no new work taken, and the farm
// carrying on by itself once space returns.
#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iterator>

#include "common/base/log.h"
#include "server/await.h"
#include "server/band_files.h"
#include "server/coordinator.h"
#include "server/metrics.h"
#include "server/syncs.h"

namespace locus::farm {
namespace fs = std::filesystem;
namespace {

// A result's encoded pixels checked as decode_band would decode them
// (common/farm/band_codec.h), without making the floats: the store and the
// frame take the bytes as they came. What does not decode is named in
// `malformed`, for the scheduler to refuse. A failed or handed-back band has
// no pixels to check.
void check_pixels(BandOutput& o) {
  if (o.handed_back || !o.error.empty()) return;
  const bool floats = o.encoded.encoding == BandEncoding::kFloat32 && o.encoded.bytes.empty();
  if (!floats) {
    if (!o.rgb.empty()) {
      o.malformed = "both float rgb and encoded pixels";
    } else if (Status s = check_band(o.encoded); !s.ok()) {
      o.malformed = s.message();
    }
    o.rgb.clear();
  }
  // The cost counts, for as many pixels as came (the scheduler checks
  // that count against the lease).
  if (o.malformed.empty() && !o.cost.empty()) {
    const int64_t pixels = floats ? static_cast<int64_t>(o.rgb.size() / 3)
                                  : static_cast<int64_t>(o.encoded.width) * o.encoded.rows;
    if (Status s = check_band_cost(o.cost, pixels); !s.ok()) o.malformed = s.message();
  }
}

}  // namespace

Status Coordinator::persist() {
  std::vector<Event> events = scheduler_.take_events();
  if (crashed_) return Status(Code::kAborted, "crashed (test)");
  // Each accepted band's record, in the transaction that says "done".
  if (!band_records_.empty()) {
    for (Event& e : events) {
      auto* d = std::get_if<event::BandDone>(&e);
      if (!d) continue;
      auto it = band_records_.find({d->job_id, d->frame, d->band});
      if (it == band_records_.end()) continue;
      d->pixels = std::move(it->second);
      band_records_.erase(it);
    }
  }
  metrics_->observe(events);
  // A job that ends and is to be told so: pending in the same transaction.
  std::vector<JobInfo> ended;
  if (job_ended_) {
    const size_t n = events.size();
    for (size_t i = 0; i < n; ++i) {
      const auto* c = std::get_if<event::JobStateChanged>(&events[i]);
      if (!c || !is_terminal(c->state)) continue;
      auto info = scheduler_.job(c->job_id);
      if (!info.ok() || (!notify_every_job_ && info->spec.notify_url.empty())) continue;
      events.push_back(event::JobNotified{c->job_id, event::NotifyPhase::kPending, ""});
      ended.push_back(std::move(*info));
    }
  }
  // What an earlier transaction failed to store goes first, in order.
  if (!unstored_.empty()) {
    events.insert(events.begin(), std::make_move_iterator(unstored_.begin()),
                  std::make_move_iterator(unstored_.end()));
    unstored_.clear();
  }
  if (!storage_trouble_.ok() && !storage_retry_) {
    // In trouble: kept until check_storage() tries again.
    unstored_ = std::move(events);
    for (const JobInfo& j : ended) job_ended_(j);
    return storage_trouble_;
  }
  Status s = store_ ? store_->apply(events) : Status::Ok();
  if (!s.ok()) {
    // Kept, in memory, for the next transaction (a full disk: until space
    // returns); the coordinator takes no new work meanwhile.
    if (storage_trouble_.ok()) {
      spdlog::error("{} ({} changes kept until they can be stored)", s.message(), events.size());
    }
    unstored_ = std::move(events);
    storage_failed(s);
  }
  for (const JobInfo& j : ended) job_ended_(j);
  return s;
}

uint64_t Coordinator::free_bytes() const {
  if (options_.data_dir.empty()) return UINT64_MAX;  // no store on disk
  std::error_code ec;
  const fs::space_info space = fs::space(options_.data_dir, ec);
  return ec ? 0 : space.available;
}

Status Coordinator::storage_refusal(const char* what) const {
  if (storage_trouble_.ok()) return Status::Ok();
  std::string m = "the coordinator cannot write to its data directory ";
  m.append(options_.data_dir)
      .append(" (")
      .append(storage_trouble_.message())
      .append("): ")
      .append(what)
      .append(" until it can; nothing acknowledged is lost");
  // Not UNAVAILABLE, which clients read as "cannot reach the farm" and
  // retry: the farm is there, its disk is full.
  return Status(Code::kResourceExhausted, m);
}

void Coordinator::storage_failed(const Status& why) {
  if (!storage_trouble_.ok()) return;
  storage_trouble_ = why;
  trouble_checked_ = SteadyClock::now();
  spdlog::error(
      "storage: {}; {} bytes free in {}: no new jobs, leases or results until it can be written "
      "again (checked every second)",
      why.message(), free_bytes(), options_.data_dir);
}

void Coordinator::check_storage() {
  if (storage_trouble_.ok() || stopping_) return;
  const TimePoint now = SteadyClock::now();
  if (now - trouble_checked_ < std::chrono::seconds(1)) return;
  trouble_checked_ = now;
  if (free_bytes() < options_.min_free_bytes) return;
  // Space again: what was kept goes into the store first.
  storage_retry_ = true;
  const Status stored = persist();
  storage_retry_ = false;
  if (!stored.ok()) return;
  spdlog::info("storage: {} can be written again ({} bytes free): carrying on, {} frames to write",
               options_.data_dir, free_bytes(), held_frames_.size());
  storage_trouble_ = Status::Ok();
  for (FrameReady& f : held_frames_) to_write_.push_back(std::move(f));
  held_frames_.clear();
  write_ready_.notify_all();
  polls_all_ = true;  // the parked polls may lease again
  changed_.notify_all();
}

bool Coordinator::hold_frame(const FrameReady& f, const Status& written) {
  if (written.ok()) return false;
  // A frame that found no space waits for it; any other failure is the
  // job's (Scheduler::frame_written fails it).
  const bool no_space = written.message().find(std::strerror(ENOSPC)) != std::string::npos ||
                        free_bytes() < options_.min_free_bytes;
  if (!no_space) return false;
  held_frames_.push_back(f);
  storage_failed(Status(Code::kResourceExhausted, "frame " + std::to_string(f.frame) + " of job " +
                                                      f.job_id + ": " + written.message()));
  return true;
}

void Coordinator::complete_band_async(BandOutput output, CompleteDone done) {
  std::vector<BandOutput> outputs;
  outputs.push_back(std::move(output));
  std::vector<CompleteDone> dones;
  dones.push_back(std::move(done));
  complete_bands_async(std::move(outputs), std::move(dones));
}

void Coordinator::complete_bands_async(std::vector<BandOutput> outputs,
                                       std::vector<CompleteDone> dones) {
  const size_t n = outputs.size();
  for (size_t i = 0; i < n; ++i) {
    // Checked (encoding, size) outside the lock; the store keeps the bytes
    // as they came.
    check_pixels(outputs[i]);
    const std::string& malformed = outputs[i].malformed;
    if (malformed.empty()) continue;
    // The scheduler charges it (as pixels of the wrong size) if the lease
    // stands; the worker hears what was wrong either way.
    dones[i] = [done = std::move(dones[i]), malformed,
                lease = outputs[i].lease_id](Result<CompleteOutcome> r) {
      if (r.ok() || r.status().code() == Code::kInvalidArgument) {
        std::string m = "lease '";
        m.append(lease).append("': malformed pixels: ").append(malformed);
        r = InvalidArgument(m);
      }
      done(std::move(r));
    };
  }
  // Answers given after the lock is let go: refusals, failures, hand-backs.
  std::vector<std::pair<CompleteDone, Result<CompleteOutcome>>> now;
  std::unique_lock lk(mu_);
  if (!storage_trouble_.ok()) {
    // Not taken: the leases stand (or lapse, and the bands are rendered
    // again); nothing the worker sent is half kept.
    Status refused = storage_refusal("results are refused");
    lk.unlock();
    for (CompleteDone& done : dones) done(refused);
    return;
  }
  // The records are made outside the lock (a copy and a checksum of the
  // pixels); a lease may lapse meanwhile, or another copy win: then
  // complete_band() below drops the result.
  std::vector<std::optional<BandTarget>> targets(n);
  for (size_t i = 0; i < n; ++i) targets[i] = scheduler_.result_target(outputs[i]);
  lk.unlock();
  std::vector<std::string> records(n);
  for (size_t i = 0; i < n; ++i) {
    if (!targets[i]) continue;
    const BandPixels rows{targets[i]->width, targets[i]->y0, targets[i]->y1};
    records[i] = pack_band(rows, stored_band(outputs[i], rows), outputs[i].cost);
  }
  lk.lock();
  bool refusals = false;
  for (size_t i = 0; i < n; ++i) {
    std::optional<BandTarget> target =
        targets[i] ? scheduler_.result_target(outputs[i]) : std::nullopt;
    std::optional<BandLogScope> log_scope;
    if (target) log_scope.emplace(target->job_id, target->frame, target->band);
    auto r = scheduler_.complete_band(outputs[i]);
    if (!target || !r.ok() || !r->accepted) {
      // Nothing to make durable: a refusal, a failure, a hand-back.
      refusals = true;
      now.emplace_back(std::move(dones[i]), std::move(r));
      continue;
    }
    // Accepted: its record goes into the store with the band's "done" (the
    // next persist()), and the worker hears "accepted" once that
    // transaction is on disk with the rest of its batch (commit_loop()).
    band_records_[{target->job_id, target->frame, target->band}] = std::move(records[i]);
    std::optional<FrameReady> frame = std::move(r->frame);
    r->frame.reset();
    commits_.push_back({std::move(dones[i]), std::move(*r), std::move(frame), SteadyClock::now()});
  }
  changed_.notify_all();
  if (refusals) persist();
  if (commits_.size() > 0) commit_ready_.notify_one();
  lk.unlock();
  for (auto& [done, r] : now) done(std::move(r));
}

Result<CompleteOutcome> Coordinator::complete_band(BandOutput output) {
  return await_answer<Result<CompleteOutcome>>(
      [&](CompleteDone done) { complete_band_async(std::move(output), std::move(done)); });
}

void Coordinator::commit_loop() {
  // Group commit (docs/farm.md "Durability"): the bands accepted while the
  // last batch was being synced, or within group_commit of the first of
  // them, are made durable together: one transaction (persist()), one sync
  // of the store's log, then every worker of the batch hears "accepted".
  constexpr size_t kMaxBatch = 512;
  std::unique_lock lk(mu_);
  for (;;) {
    commit_ready_.wait(lk, [&] { return stopping_ || !commits_.empty(); });
    if (commits_.empty()) return;  // stopping, and nothing left
    if (options_.fsync && !stopping_) {
      const TimePoint until = commits_.front().queued + options_.group_commit;
      commit_ready_.wait_until(lk, until,
                               [&] { return stopping_ || commits_.size() >= kMaxBatch; });
    }
    Status s = persist();
    std::deque<Commit> batch = std::move(commits_);
    commits_.clear();
    // A frame is written once its bands are stored: now, or when the
    // storage is back (a failed transaction's bands are kept, unstored_).
    for (Commit& c : batch) {
      if (c.frame) (s.ok() ? to_write_ : held_frames_).push_back(std::move(*c.frame));
    }
    if (s.ok()) write_ready_.notify_all();
    lk.unlock();
    if (s.ok() && options_.fsync) s = sync_log();
    for (Commit& c : batch) {
      if (s.ok()) {
        c.done(std::move(c.outcome));
      } else {
        c.done(Status(Code::kUnavailable, "the coordinator cannot store the band: " + s.message()));
      }
    }
    lk.lock();
  }
}

Status Coordinator::sync_log() {
  // The WAL holds every transaction committed since the last checkpoint;
  // fdatasync on it is the sync SQLite's synchronous=FULL does at each
  // commit (store.cpp), done here once per batch and outside the lock.
  if (log_fd_ < 0) {
    const std::string wal = (fs::path(options_.data_dir) / "locus.db-wal").string();
    log_fd_ = ::open(wal.c_str(), O_RDONLY | O_CLOEXEC);
    if (log_fd_ < 0) return Internal(wal + ": cannot open to sync: " + std::strerror(errno));
  }
  if (counted_fdatasync(log_fd_) != 0) {
    return Internal(options_.data_dir + "/locus.db-wal: fdatasync failed: " + std::strerror(errno));
  }
  log_syncs_.fetch_add(1, std::memory_order_relaxed);
  return Status::Ok();
}

void Coordinator::close_store_files() {
  {
    std::lock_guard lk(reader_mu_);
    reader_.reset();
  }
  if (log_fd_ >= 0) ::close(log_fd_);
  log_fd_ = -1;
  band_records_.clear();
}

Result<std::string> Coordinator::read_band_record(const std::string& job_id, int frame, int band) {
  std::lock_guard lk(reader_mu_);
  if (!reader_) {
    auto r = JobStore::open_reader((fs::path(options_.data_dir) / "locus.db").string());
    if (!r.ok()) return r.status();
    reader_ = std::move(*r);
  }
  return reader_->band_record(job_id, frame, band);
}

}  // namespace locus::farm
