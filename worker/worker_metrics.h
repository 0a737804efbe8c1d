// The worker's own Prometheus series (prometheus-cpp), served by
// `locus-worker --metrics ADDR` through farm::MetricsEndpoint. No network
// here: WorkerClient reports what happens, the tests read metrics_text().
#pragma once

#include <prometheus/counter.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

#include <cstdint>
#include <memory>
#include <string>

namespace locus::farm {

class WorkerMetrics {
 public:
  // How a band in hand ended on this worker.
  enum class BandEnd { kDone, kFailed, kDropped, kHandedBack };

  WorkerMetrics();
  WorkerMetrics(const WorkerMetrics&) = delete;
  WorkerMetrics& operator=(const WorkerMetrics&) = delete;

  void set_connected(bool connected);
  void registered();
  void band_started();
  // `render_seconds` < 0: the band was not rendered.
  void band_ended(BandEnd end, double render_seconds);
  void scene_fetched();
  // Serialized sizes of the messages this worker sent and received.
  void add_bytes(uint64_t received, uint64_t sent);

  const std::shared_ptr<prometheus::Registry>& registry() const { return registry_; }

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  prometheus::Gauge& connected_;
  prometheus::Gauge& busy_;
  prometheus::Counter& registrations_;
  prometheus::Family<prometheus::Counter>& bands_;
  prometheus::Histogram& render_seconds_;
  prometheus::Counter& scenes_;
  prometheus::Counter& received_;
  prometheus::Counter& sent_;
};

}  // namespace locus::farm
