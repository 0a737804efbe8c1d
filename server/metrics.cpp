#include "server/metrics.h"

namespace locus::farm {

namespace {

// The outcomes charged to a band: its failures.
constexpr std::array<LeaseOutcome, 5> kFailures = {LeaseOutcome::kFailed, LeaseOutcome::kMalformed,
                                                   LeaseOutcome::kLapsed, LeaseOutcome::kSilent,
                                                   LeaseOutcome::kTimedOut};

}  // namespace

CoordinatorMetrics::CoordinatorMetrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      bands_(gauges(*registry_, "locus_bands",
                    "Bands of the jobs the coordinator holds, by state: queued (waiting for a "
                    "worker), running (leased), done")),
      bands_queued_(bands_.Add({{"state", "queued"}})),
      bands_running_(bands_.Add({{"state", "running"}})),
      bands_done_(bands_.Add({{"state", "done"}})),
      jobs_(gauges(*registry_, "locus_jobs", "Jobs the coordinator holds, by state")),
      workers_(gauge(*registry_, "locus_workers_connected",
                     "Workers registered and not dropped for silence")),
      jobs_submitted_(counter(*registry_, "locus_jobs_submitted_total",
                              "Jobs accepted since the coordinator started")),
      jobs_finished_(counters(*registry_, "locus_jobs_finished_total",
                              "Jobs that ended since the coordinator started, by final state")),
      bands_completed_(counter(*registry_, "locus_bands_completed_total",
                               "Band results accepted since the coordinator started")),
      band_seconds_(band_seconds(*registry_, "locus_band_render_seconds",
                                 "Seconds from a band's lease to its accepted result (rendering, "
                                 "scene fetch and transfer)")),
      failures_(counters(*registry_, "locus_band_failures_total",
                         "Failed band attempts charged to the band, by reason: failed (the "
                         "worker's error), malformed (pixels), lapsed (lease not renewed), "
                         "silent (worker dropped)")),
      retries_(counter(*registry_, "locus_band_retries_total",
                       "Bands put back in the queue to be leased again (after a failure, a "
                       "lapse, a silent worker or a hand-back)")),
      speculative_(counter(*registry_, "locus_speculative_leases_total",
                           "Second leases of bands running far longer than their peers")),
      user_band_seconds_(counters(*registry_, "locus_user_band_seconds_total",
                                  "Band-seconds (lease to end) of each user's attempts, by kind: "
                                  "done (accepted), failed (charged), lost (races lost, lapses, "
                                  "revocations, preemptions, hand-backs)")),
      user_cpu_seconds_(counters(*registry_, "locus_user_render_cpu_seconds_total",
                                 "Render CPU seconds of each user's accepted bands")),
      received_(counters(*registry_, "locus_rpc_received_bytes_total",
                         "Bytes of request messages received, by call")),
      sent_(counters(*registry_, "locus_rpc_sent_bytes_total",
                     "Bytes of response messages sent, by call")),
      syncs_(counters(*registry_, "locus_syncs_total",
                      "Syncs asked of the disk since the coordinator started, by whose: store "
                      "(SQLite's), files (the group commit's log sync, frames, directories)")),
      store_syncs_(syncs_.Add({{"by", "store"}})),
      file_syncs_(syncs_.Add({{"by", "files"}})) {
  // Every series exists from the start, at zero.
  for (const auto& [s, name] : kJobStateLabels) {
    jobs_by_state_[static_cast<size_t>(s)] = &jobs_.Add({{"state", std::string(name)}});
    if (is_terminal(s)) jobs_finished_.Add({{"state", std::string(name)}});
  }
  for (LeaseOutcome o : kFailures) failures_.Add({{"reason", lease_outcome_name(o)}});
}

void CoordinatorMetrics::observe(const std::vector<Event>& events) {
  for (const Event& e : events) {
    std::visit(
        [&](const auto& ev) {
          using T = std::decay_t<decltype(ev)>;
          if constexpr (std::is_same_v<T, event::JobAdded>) {
            jobs_submitted_.Increment();
          } else if constexpr (std::is_same_v<T, event::JobStateChanged>) {
            if (is_terminal(ev.state))
              jobs_finished_.Add({{"state", job_state_name(ev.state)}}).Increment();
          } else if constexpr (std::is_same_v<T, event::LeaseGranted>) {
            if (ev.speculative) speculative_.Increment();
          } else if constexpr (std::is_same_v<T, event::LeaseEnded>) {
            if (is_charged(ev.outcome))
              failures_.Add({{"reason", lease_outcome_name(ev.outcome)}}).Increment();
            if (ev.requeued) retries_.Increment();
            user_band_seconds_
                .Add({{"user", ev.owner}, {"kind", is_charged(ev.outcome) ? "failed" : "lost"}})
                .Increment(ev.seconds);
          } else if constexpr (std::is_same_v<T, event::BandDone>) {
            bands_completed_.Increment();
            band_seconds_.Observe(ev.seconds);
            user_band_seconds_.Add({{"user", ev.owner}, {"kind", "done"}}).Increment(ev.seconds);
            user_cpu_seconds_.Add({{"user", ev.owner}}).Increment(ev.cpu_seconds);
          }
        },
        e);
  }
}

void CoordinatorMetrics::set_counts(const FarmCounts& c) {
  bands_queued_.Set(static_cast<double>(c.bands_queued));
  bands_running_.Set(static_cast<double>(c.bands_running));
  bands_done_.Set(static_cast<double>(c.bands_done));
  for (size_t i = 0; i < jobs_by_state_.size(); ++i)
    jobs_by_state_[i]->Set(static_cast<double>(c.jobs[i]));
  workers_.Set(static_cast<double>(c.workers));
}

void CoordinatorMetrics::set_syncs(const SyncCounts& s) {
  // Counters only go up: each takes what was counted since the last scrape.
  store_syncs_.Increment(static_cast<double>(s.store) - store_syncs_.Value());
  file_syncs_.Increment(static_cast<double>(s.files) - file_syncs_.Value());
}

void CoordinatorMetrics::add_bytes(std::string_view call, uint64_t received, uint64_t sent) {
  const prometheus::Labels labels{{"call", std::string(call)}};
  received_.Add(labels).Increment(static_cast<double>(received));
  sent_.Add(labels).Increment(static_cast<double>(sent));
}

}  // namespace locus::farm
