// The coordinator's Prometheus series. Its counters and its histogram
// follow the Scheduler's events (Coordinator::persist() hands them over);
// its gauges are read from the Scheduler at each scrape. No gRPC here: the
// gRPC adapter only reports the bytes of each call. The endpoint and the
// helpers are common/farm/metrics.h; docs/deploy.md "Metrics" lists every
// series.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "common/farm/metrics.h"
#include "server/journal.h"
#include "server/syncs.h"

namespace locus::farm {

class CoordinatorMetrics {
 public:
  CoordinatorMetrics();
  CoordinatorMetrics(const CoordinatorMetrics&) = delete;
  CoordinatorMetrics& operator=(const CoordinatorMetrics&) = delete;

  // Counters and the band histogram, from one call's events.
  void observe(const std::vector<Event>& events);
  // The gauges.
  void set_counts(const FarmCounts& counts);
  // The syncs counted so far (server/syncs.h), by whose they were.
  void set_syncs(const SyncCounts& syncs);
  // The serialized size of one call's request and response messages (each
  // message of a stream), by call ("WorkerService.CompleteBand").
  void add_bytes(std::string_view call, uint64_t received, uint64_t sent);

  const std::shared_ptr<prometheus::Registry>& registry() const { return registry_; }

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Family<prometheus::Gauge>& bands_;
  prometheus::Gauge& bands_queued_;
  prometheus::Gauge& bands_running_;
  prometheus::Gauge& bands_done_;
  prometheus::Family<prometheus::Gauge>& jobs_;
  std::array<prometheus::Gauge*, kJobStateLabels.size()> jobs_by_state_{};
  prometheus::Gauge& workers_;
  prometheus::Counter& jobs_submitted_;
  prometheus::Family<prometheus::Counter>& jobs_finished_;
  prometheus::Counter& bands_completed_;
  prometheus::Histogram& band_seconds_;
  prometheus::Family<prometheus::Counter>& failures_;
  prometheus::Counter& retries_;
  prometheus::Counter& speculative_;
  prometheus::Family<prometheus::Counter>& user_band_seconds_;
  prometheus::Family<prometheus::Counter>& user_cpu_seconds_;
  prometheus::Family<prometheus::Counter>& received_;
  prometheus::Family<prometheus::Counter>& sent_;
  prometheus::Family<prometheus::Counter>& syncs_;
  prometheus::Counter& store_syncs_;
  prometheus::Counter& file_syncs_;
};

}  // namespace locus::farm
