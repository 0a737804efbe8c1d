// Prometheus metrics (prometheus-cpp): the /metrics HTTP endpoint that the
// coordinator and the worker serve on --metrics ADDR, and the coordinator's
// series. The coordinator's counters and its histogram follow the
// Scheduler's events (Coordinator::persist() hands them over); its gauges
// are read from the Scheduler at each scrape. No gRPC here: the gRPC
// adapter only reports the bytes of each call. docs/deploy.md "Metrics"
// lists every series.
#pragma once

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/status.h"
#include "server/journal.h"

namespace prometheus {
class Exposer;
}

namespace locus::farm {

// Buckets of the band-seconds histograms, coordinator and worker: bands
// take from milliseconds (a row of sky) to minutes (glass at 16k).
const prometheus::Histogram::BucketBoundaries& band_seconds_buckets();

// A family registered in `registry`, and the series of a family without
// labels: the one-liners every series below is made with.
prometheus::Family<prometheus::Counter>& counters(prometheus::Registry& registry,
                                                  const std::string& name, const std::string& help);
prometheus::Family<prometheus::Gauge>& gauges(prometheus::Registry& registry,
                                              const std::string& name, const std::string& help);
prometheus::Counter& counter(prometheus::Registry& registry, const std::string& name,
                             const std::string& help);
prometheus::Gauge& gauge(prometheus::Registry& registry, const std::string& name,
                         const std::string& help);
// A histogram of band seconds (band_seconds_buckets()).
prometheus::Histogram& band_seconds(prometheus::Registry& registry, const std::string& name,
                                    const std::string& help);

// A registry in the text exposition format, as GET /metrics returns it.
std::string metrics_text(const prometheus::Registry& registry);

// GET http://ADDR/metrics: the registry, after `before_scrape` (gauges read
// at scrape time) has run.
class MetricsEndpoint {
 public:
  // ADDR is HOST:PORT ("0.0.0.0:7002"; port 0: any free port). Unavailable
  // when the address cannot be bound.
  static Result<std::unique_ptr<MetricsEndpoint>> start(
      const std::string& address, std::shared_ptr<prometheus::Registry> registry,
      std::function<void()> before_scrape = {});
  ~MetricsEndpoint();
  int port() const { return port_; }

 private:
  class Source;
  MetricsEndpoint() = default;
  std::shared_ptr<Source> source_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  int port_ = 0;
};

class CoordinatorMetrics {
 public:
  CoordinatorMetrics();
  CoordinatorMetrics(const CoordinatorMetrics&) = delete;
  CoordinatorMetrics& operator=(const CoordinatorMetrics&) = delete;

  // Counters and the band histogram, from one call's events.
  void observe(const std::vector<Event>& events);
  // The gauges.
  void set_counts(const FarmCounts& counts);
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
  std::array<prometheus::Gauge*, 5> jobs_by_state_{};
  prometheus::Gauge& workers_;
  prometheus::Counter& jobs_submitted_;
  prometheus::Family<prometheus::Counter>& jobs_finished_;
  prometheus::Counter& bands_completed_;
  prometheus::Histogram& band_seconds_;
  prometheus::Family<prometheus::Counter>& failures_;
  prometheus::Counter& retries_;
  prometheus::Counter& speculative_;
  prometheus::Family<prometheus::Counter>& received_;
  prometheus::Family<prometheus::Counter>& sent_;
};

}  // namespace locus::farm
