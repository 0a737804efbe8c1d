#include "worker/worker_metrics.h"

#include <string>

#include "common/base/labels.h"
#include "common/farm/metrics.h"

namespace locus::farm {
namespace {

// The `outcome` label of locus_worker_bands_total (docs/deploy.md "Metrics").
constexpr Labels<WorkerMetrics::BandEnd, 4> kBandEndLabels = {
    {{WorkerMetrics::BandEnd::kDone, "done"},
     {WorkerMetrics::BandEnd::kFailed, "failed"},
     {WorkerMetrics::BandEnd::kDropped, "dropped"},
     {WorkerMetrics::BandEnd::kHandedBack, "handed_back"}}};

std::string band_end_name(WorkerMetrics::BandEnd end) {
  return std::string(label_name(kBandEndLabels, end, "?"));
}

}  // namespace

WorkerMetrics::WorkerMetrics()
    : registry_(std::make_shared<prometheus::Registry>()),
      connected_(gauge(*registry_, "locus_worker_connected",
                       "1 while the worker is registered with its coordinator and reaches it")),
      busy_(gauge(*registry_, "locus_worker_busy", "1 while the worker holds a band")),
      registrations_(counter(*registry_, "locus_worker_registrations_total",
                             "Registrations with the coordinator (again after a restart of it)")),
      bands_(counters(*registry_, "locus_worker_bands_total",
                      "Bands this worker took, by how they ended: done (result sent), failed "
                      "(error sent), dropped (lease revoked or result refused), handed_back")),
      render_seconds_(band_seconds(*registry_, "locus_worker_band_render_seconds",
                                   "Seconds spent rendering one band on this worker")),
      scenes_(counter(*registry_, "locus_worker_scenes_fetched_total",
                      "Scenes fetched from the coordinator (once per scene, cached after)")),
      received_(counter(*registry_, "locus_worker_received_bytes_total",
                        "Bytes of messages received from the coordinator")),
      sent_(counter(*registry_, "locus_worker_sent_bytes_total",
                    "Bytes of messages sent to the coordinator")) {
  for (const auto& [end, name] : kBandEndLabels) bands_.Add({{"outcome", std::string(name)}});
}

void WorkerMetrics::set_connected(bool connected) { connected_.Set(connected ? 1 : 0); }
void WorkerMetrics::registered() { registrations_.Increment(); }
void WorkerMetrics::band_started() { busy_.Set(1); }

void WorkerMetrics::band_ended(BandEnd end, double render_seconds) {
  busy_.Set(0);
  bands_.Add({{"outcome", band_end_name(end)}}).Increment();
  if (render_seconds >= 0) render_seconds_.Observe(render_seconds);
}

void WorkerMetrics::scene_fetched() { scenes_.Increment(); }

void WorkerMetrics::add_bytes(uint64_t received, uint64_t sent) {
  received_.Increment(static_cast<double>(received));
  sent_.Increment(static_cast<double>(sent));
}

}  // namespace locus::farm
