#include "server/metrics.h"

#include <prometheus/collectable.h>
#include <prometheus/exposer.h>
#include <prometheus/text_serializer.h>

#include <exception>
#include <type_traits>
#include <variant>

namespace locus::farm {

const prometheus::Histogram::BucketBoundaries& band_seconds_buckets() {
  static const prometheus::Histogram::BucketBoundaries buckets = {
      0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 120, 300};
  return buckets;
}

std::string metrics_text(const prometheus::Registry& registry) {
  return prometheus::TextSerializer().Serialize(registry.Collect());
}

// What the exposer collects: the registry, once `before_scrape` has
// brought its gauges up to date.
class MetricsEndpoint::Source final : public prometheus::Collectable {
 public:
  Source(std::shared_ptr<prometheus::Registry> registry, std::function<void()> before_scrape)
      : registry_(std::move(registry)), before_scrape_(std::move(before_scrape)) {}
  std::vector<prometheus::MetricFamily> Collect() const override {
    if (before_scrape_) before_scrape_();
    return registry_->Collect();
  }

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  std::function<void()> before_scrape_;
};

Result<std::unique_ptr<MetricsEndpoint>> MetricsEndpoint::start(
    const std::string& address, std::shared_ptr<prometheus::Registry> registry,
    std::function<void()> before_scrape) {
  std::unique_ptr<MetricsEndpoint> e(new MetricsEndpoint);
  e->source_ = std::make_shared<Source>(std::move(registry), std::move(before_scrape));
  try {
    // One thread: Prometheus scrapes every few seconds at most.
    e->exposer_ = std::make_unique<prometheus::Exposer>(address, 1);
  } catch (const std::exception& ex) {
    return Status(Code::kUnavailable, "--metrics " + address + ": cannot listen (" + ex.what() +
                                          "); give HOST:PORT with a free port, e.g. 0.0.0.0:7002");
  }
  e->exposer_->RegisterCollectable(e->source_);
  const std::vector<int> ports = e->exposer_->GetListeningPorts();
  e->port_ = ports.empty() ? 0 : ports.front();
  return e;
}

MetricsEndpoint::~MetricsEndpoint() = default;

namespace {

// The outcomes charged to a band: its failures.
constexpr std::array<LeaseOutcome, 4> kFailures = {LeaseOutcome::kFailed, LeaseOutcome::kMalformed,
                                                   LeaseOutcome::kLapsed, LeaseOutcome::kSilent};
constexpr std::array<JobState, 5> kJobStates = {JobState::kQueued, JobState::kRunning,
                                                JobState::kSucceeded, JobState::kFailed,
                                                JobState::kCancelled};

}  // namespace

CoordinatorMetrics::CoordinatorMetrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      bands_(prometheus::BuildGauge()
                 .Name("locus_bands")
                 .Help("Bands of the jobs the coordinator holds, by state: queued (waiting for a "
                       "worker), running (leased), done")
                 .Register(*registry_)),
      bands_queued_(bands_.Add({{"state", "queued"}})),
      bands_running_(bands_.Add({{"state", "running"}})),
      bands_done_(bands_.Add({{"state", "done"}})),
      jobs_(prometheus::BuildGauge()
                .Name("locus_jobs")
                .Help("Jobs the coordinator holds, by state")
                .Register(*registry_)),
      workers_(prometheus::BuildGauge()
                   .Name("locus_workers_connected")
                   .Help("Workers registered and not dropped for silence")
                   .Register(*registry_)
                   .Add({})),
      jobs_submitted_(prometheus::BuildCounter()
                          .Name("locus_jobs_submitted_total")
                          .Help("Jobs accepted since the coordinator started")
                          .Register(*registry_)
                          .Add({})),
      jobs_finished_(prometheus::BuildCounter()
                         .Name("locus_jobs_finished_total")
                         .Help("Jobs that ended since the coordinator started, by final state")
                         .Register(*registry_)),
      bands_completed_(prometheus::BuildCounter()
                           .Name("locus_bands_completed_total")
                           .Help("Band results accepted since the coordinator started")
                           .Register(*registry_)
                           .Add({})),
      band_seconds_(prometheus::BuildHistogram()
                        .Name("locus_band_render_seconds")
                        .Help("Seconds from a band's lease to its accepted result (rendering, "
                              "scene fetch and transfer)")
                        .Register(*registry_)
                        .Add({}, band_seconds_buckets())),
      failures_(prometheus::BuildCounter()
                    .Name("locus_band_failures_total")
                    .Help("Failed band attempts charged to the band, by reason: failed (the "
                          "worker's error), malformed (pixels), lapsed (lease not renewed), "
                          "silent (worker dropped)")
                    .Register(*registry_)),
      retries_(prometheus::BuildCounter()
                   .Name("locus_band_retries_total")
                   .Help("Bands put back in the queue to be leased again (after a failure, a "
                         "lapse, a silent worker or a hand-back)")
                   .Register(*registry_)
                   .Add({})),
      speculative_(prometheus::BuildCounter()
                       .Name("locus_speculative_leases_total")
                       .Help("Second leases of bands running far longer than their peers")
                       .Register(*registry_)
                       .Add({})),
      received_(prometheus::BuildCounter()
                    .Name("locus_rpc_received_bytes_total")
                    .Help("Bytes of request messages received, by call")
                    .Register(*registry_)),
      sent_(prometheus::BuildCounter()
                .Name("locus_rpc_sent_bytes_total")
                .Help("Bytes of response messages sent, by call")
                .Register(*registry_)) {
  // Every series exists from the start, at zero.
  for (JobState s : kJobStates) {
    jobs_by_state_[static_cast<size_t>(s)] = &jobs_.Add({{"state", job_state_name(s)}});
    if (is_terminal(s)) jobs_finished_.Add({{"state", job_state_name(s)}});
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
          } else if constexpr (std::is_same_v<T, event::BandDone>) {
            bands_completed_.Increment();
            band_seconds_.Observe(ev.seconds);
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

void CoordinatorMetrics::add_bytes(std::string_view call, uint64_t received, uint64_t sent) {
  const prometheus::Labels labels{{"call", std::string(call)}};
  received_.Add(labels).Increment(static_cast<double>(received));
  sent_.Add(labels).Increment(static_cast<double>(sent));
}

}  // namespace locus::farm
