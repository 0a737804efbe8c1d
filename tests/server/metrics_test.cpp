// The farm's Prometheus series: counted from the Scheduler's events and
// read from its state without a network (the registry's text format), the
// worker's own series, and GET /metrics over 127.0.0.1 on a farm in this
// process.
#include "server/metrics.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <regex>
#include <string>

#include "server/scheduler.h"
#include "tests/farm_fixture.h"
#include "tests/server/scheduler_doubles.h"
#include "worker/worker_metrics.h"

namespace locus::farm {
namespace {

using test_doubles::FakeClock;
using test_doubles::pixels;
using testing_farm::sample;

// GET http://127.0.0.1:PORT/metrics with a plain socket: status line and body.
std::string http_get(int port, const std::string& path) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  EXPECT_GE(fd, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  timeval timeout{10, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    close(fd);
    return "";
  }
  const std::string req = "GET " + path + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  EXPECT_EQ(write(fd, req.data(), req.size()), static_cast<ssize_t>(req.size()));
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(fd, buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  close(fd);
  return out;
}

// The coordinator's series that docs/deploy.md promises.
const std::vector<std::string> kCoordinatorSeries = {
    R"(locus_bands{state="queued"})",
    R"(locus_bands{state="running"})",
    R"(locus_bands{state="done"})",
    R"(locus_jobs{state="queued"})",
    R"(locus_jobs{state="running"})",
    R"(locus_jobs{state="succeeded"})",
    R"(locus_jobs{state="failed"})",
    R"(locus_jobs{state="cancelled"})",
    "locus_workers_connected",
    "locus_band_render_seconds_count",
    "locus_band_render_seconds_sum",
    R"(locus_band_render_seconds_bucket{le="+Inf"})",
    R"(locus_band_failures_total{reason="failed"})",
    R"(locus_band_failures_total{reason="lapsed"})",
    "locus_band_retries_total",
    "locus_bands_completed_total",
    "locus_jobs_submitted_total",
    R"(locus_rpc_received_bytes_total{call="WorkerService.CompleteBand"})",
    R"(locus_rpc_sent_bytes_total{call="WorkerService.GetTask"})",
};
const std::vector<std::string> kWorkerSeries = {
    "locus_worker_connected",
    "locus_worker_busy",
    R"(locus_worker_bands_total{outcome="done"})",
    "locus_worker_band_render_seconds_count",
    "locus_worker_scenes_fetched_total",
    "locus_worker_received_bytes_total",
    "locus_worker_sent_bytes_total",
};

JobSpec spec(int frames, int bands) {
  return test_doubles::job_spec(4, 8, 1, frames, bands, "m_####.png");
}

// Scheduler events in, series out: what each event counts.
TEST(CoordinatorMetrics, CountsSchedulerEvents) {
  FakeClock clock;
  Scheduler s(SchedulerOptions{Millis(1000), Millis(60000), 2, 0}, clock.fn());
  CoordinatorMetrics m;
  auto scrape = [&] {
    m.observe(s.take_events());
    m.set_counts(s.counts());
    return metrics_text(*m.registry());
  };
  std::string text = scrape();
  for (const std::string& series : kCoordinatorSeries) {
    if (series.find("rpc_") != std::string::npos) continue;  // made by the first call
    EXPECT_EQ(sample(text, series), 0) << series << "\n" << text;
  }

  const std::string a = s.add_job(spec(2, 2));  // 4 bands
  const std::string w1 = s.add_worker("host:1", 1);
  const std::string w2 = s.add_worker("host:2", 1);
  text = scrape();
  EXPECT_EQ(sample(text, "locus_jobs_submitted_total"), 1);
  EXPECT_EQ(sample(text, R"(locus_jobs{state="queued"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_bands{state="queued"})"), 4);
  EXPECT_EQ(sample(text, "locus_workers_connected"), 2);

  // w1 renders a band in 250 ms; w2 takes one and lets its lease lapse.
  BandLease t1 = **s.next_band(w1);
  BandLease t2 = **s.next_band(w2);
  text = scrape();
  EXPECT_EQ(sample(text, R"(locus_jobs{state="running"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_bands{state="running"})"), 2);
  EXPECT_EQ(sample(text, R"(locus_bands{state="queued"})"), 2);
  clock.t += Millis(250);
  ASSERT_TRUE(s.complete_band(pixels(w1, t1))->accepted);
  clock.t += Millis(1000);
  s.expire();  // t2's lease lapses: a failure charged, the band queued again
  text = scrape();
  EXPECT_EQ(sample(text, "locus_bands_completed_total"), 1);
  EXPECT_EQ(sample(text, R"(locus_bands{state="done"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_bands{state="running"})"), 0);
  EXPECT_EQ(sample(text, R"(locus_bands{state="queued"})"), 3);
  EXPECT_EQ(sample(text, R"(locus_band_failures_total{reason="lapsed"})"), 1);
  EXPECT_EQ(sample(text, "locus_band_retries_total"), 1);
  EXPECT_EQ(sample(text, "locus_band_render_seconds_count"), 1);
  EXPECT_DOUBLE_EQ(sample(text, "locus_band_render_seconds_sum"), 0.25);
  EXPECT_EQ(sample(text, R"(locus_band_render_seconds_bucket{le="0.1"})"), 0);
  EXPECT_EQ(sample(text, R"(locus_band_render_seconds_bucket{le="0.25"})"), 1);

  // The lapsed band goes to w1 (it has not failed there) and fails with an
  // error: its second failure reaches --max-attempts 2, the job fails and
  // the band is not queued again.
  BandLease again = **s.next_band(w1);
  ASSERT_EQ(again.band, t2.band);
  BandOutput err;
  err.worker_id = w1;
  err.lease_id = again.lease_id;
  err.error = "out of memory";
  ASSERT_TRUE(s.complete_band(err).ok());
  text = scrape();
  EXPECT_EQ(sample(text, R"(locus_band_failures_total{reason="failed"})"), 1);
  EXPECT_EQ(sample(text, "locus_band_retries_total"), 1)
      << "a band past its attempts is not retried";
  EXPECT_EQ(sample(text, R"(locus_jobs{state="failed"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_jobs_finished_total{state="failed"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_bands{state="queued"})"), 0) << "a failed job queues nothing";
  (void)a;
}

TEST(CoordinatorMetrics, BytesByCall) {
  CoordinatorMetrics m;
  m.add_bytes("WorkerService.CompleteBand", 1000, 10);
  m.add_bytes("WorkerService.CompleteBand", 500, 10);
  m.add_bytes("ClientService.WatchJob", 0, 42);
  const std::string text = metrics_text(*m.registry());
  EXPECT_EQ(sample(text, R"(locus_rpc_received_bytes_total{call="WorkerService.CompleteBand"})"),
            1500);
  EXPECT_EQ(sample(text, R"(locus_rpc_sent_bytes_total{call="WorkerService.CompleteBand"})"), 20);
  EXPECT_EQ(sample(text, R"(locus_rpc_sent_bytes_total{call="ClientService.WatchJob"})"), 42);
}

TEST(WorkerMetrics, CountsBandsAndBytes) {
  WorkerMetrics m;
  m.set_connected(true);
  m.registered();
  m.band_started();
  std::string text = metrics_text(*m.registry());
  EXPECT_EQ(sample(text, "locus_worker_busy"), 1);
  EXPECT_EQ(sample(text, "locus_worker_connected"), 1);
  m.band_ended(WorkerMetrics::BandEnd::kDone, 0.5);
  m.band_started();
  m.band_ended(WorkerMetrics::BandEnd::kHandedBack, -1);
  m.scene_fetched();
  m.add_bytes(300, 7000);
  text = metrics_text(*m.registry());
  EXPECT_EQ(sample(text, "locus_worker_busy"), 0);
  EXPECT_EQ(sample(text, R"(locus_worker_bands_total{outcome="done"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_worker_bands_total{outcome="handed_back"})"), 1);
  EXPECT_EQ(sample(text, R"(locus_worker_bands_total{outcome="failed"})"), 0);
  EXPECT_EQ(sample(text, "locus_worker_band_render_seconds_count"), 1) << "only rendered bands";
  EXPECT_EQ(sample(text, "locus_worker_scenes_fetched_total"), 1);
  EXPECT_EQ(sample(text, "locus_worker_registrations_total"), 1);
  EXPECT_EQ(sample(text, "locus_worker_received_bytes_total"), 300);
  EXPECT_EQ(sample(text, "locus_worker_sent_bytes_total"), 7000);
}

TEST(MetricsEndpoint, RefusesAnAddressInUse) {
  auto first = MetricsEndpoint::start("127.0.0.1:0", std::make_shared<prometheus::Registry>());
  ASSERT_TRUE(first.ok()) << first.status().message();
  const std::string taken = "127.0.0.1:" + std::to_string((*first)->port());
  auto second = MetricsEndpoint::start(taken, std::make_shared<prometheus::Registry>());
  ASSERT_FALSE(second.ok());
  EXPECT_NE(second.status().message().find("--metrics " + taken), std::string::npos)
      << second.status().message();
}

using testing_farm::FarmTest;

// A job on an in-process farm, then GET /metrics over 127.0.0.1 from the
// coordinator and from a worker: every promised series is there, with the
// job's numbers.
TEST_F(FarmTest, MetricsOverLoopbackAfterAJob) {
  start();
  add_workers(2);
  auto coordinator_endpoint =
      MetricsEndpoint::start("127.0.0.1:0", coordinator_->metrics().registry(),
                             [this] { coordinator_->refresh_metrics(); });
  ASSERT_TRUE(coordinator_endpoint.ok()) << coordinator_endpoint.status().message();
  auto worker_endpoint = MetricsEndpoint::start("127.0.0.1:0", workers_[0]->metrics().registry());
  ASSERT_TRUE(worker_endpoint.ok()) << worker_endpoint.status().message();

  const SubmitRequest r = testing_farm::request(testing_farm::kAnim, 32, 24, 1, 3, 4, "m_####.png");
  const JobInfo job = run(r);
  ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;

  const std::string response = http_get((*coordinator_endpoint)->port(), "/metrics");
  ASSERT_EQ(response.rfind("HTTP/1.1 200", 0), 0u) << response.substr(0, 200);
  for (const std::string& series : kCoordinatorSeries) {
    EXPECT_GE(sample(response, series), 0) << series << " missing";
  }
  EXPECT_EQ(sample(response, R"(locus_jobs{state="succeeded"})"), 1);
  EXPECT_EQ(sample(response, R"(locus_bands{state="done"})"), 12);
  EXPECT_EQ(sample(response, "locus_band_render_seconds_count"), 12);
  EXPECT_EQ(sample(response, "locus_workers_connected"), 2);
  // Counted, and fewer than the 3 frames' floats: a PNG job's bands travel
  // as 8-bit codes, compressed (common/farm/band_codec.h).
  const double band_bytes =
      sample(response, R"(locus_rpc_received_bytes_total{call="WorkerService.CompleteBand"})");
  EXPECT_GT(band_bytes, 0);
  EXPECT_LT(band_bytes, 32 * 24 * 3 * 12);

  const std::string worker = http_get((*worker_endpoint)->port(), "/metrics");
  ASSERT_EQ(worker.rfind("HTTP/1.1 200", 0), 0u) << worker.substr(0, 200);
  for (const std::string& series : kWorkerSeries) {
    EXPECT_GE(sample(worker, series), 0) << series << " missing";
  }
  EXPECT_EQ(sample(worker, "locus_worker_connected"), 1);
}

}  // namespace
}  // namespace locus::farm
