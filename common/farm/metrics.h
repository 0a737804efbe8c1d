// Prometheus metrics (prometheus-cpp) as every farm process serves them:
// the /metrics HTTP endpoint of --metrics ADDR, the band-seconds buckets,
// and the one-liners every series is made with. The coordinator's series
// are in server/metrics.h, the worker's in worker/worker_metrics.h;
// docs/deploy.md "Metrics" lists every series.
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

#include "common/base/status.h"

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

}  // namespace locus::farm
