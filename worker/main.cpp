// locus-worker: a stateless render worker. It dials the coordinator, takes
// bands, renders them and returns the pixels until SIGTERM/SIGINT, after
// which it finishes the band in hand and exits. It is a gRPC client of the
// coordinator; --health serves the standard health service (for probes)
// and --metrics its Prometheus series (docs/deploy.md). `locus-worker
// health ADDR` asks a health service, like `locus health`: the worker's
// image (deploy/docker/Dockerfile) carries no other binary for its probe.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <thread>

#include "common/base/log.h"
#include "common/base/status.h"
#include "common/farm/metrics.h"
#include "proto/wire/health.h"
#include "worker/worker_client.h"
#include "worker/worker_metrics.h"

namespace {

int fail(const std::string& message) {
  std::fprintf(stderr, "locus-worker: %s\n", message.c_str());
  return 2;
}

// Exit status 0 when SERVING (Docker's HEALTHCHECK), 1 otherwise.
int run_health(const std::string& address, const std::string& service) {
  auto serving = locus::rpc::check_health(address, service, {}, locus::farm::Millis(5000));
  if (!serving.ok()) return fail(serving.status().message());
  std::printf("%s\n", *serving ? "SERVING" : "NOT_SERVING");
  return *serving ? 0 : 1;
}

// --coordinator-fd: the address, one line, from a pipe or socket that the
// parent writes once its coordinator listens. The worker loads (most of its
// start: the dynamic linker) while the coordinator starts, instead of after.
locus::Result<std::string> read_address(int fd) {
  constexpr size_t kMaxAddress = 1024;
  const std::string what = "--coordinator-fd " + std::to_string(fd);
  std::string line;
  locus::Status problem = locus::Status::Ok();
  for (;;) {
    char c;
    const ssize_t n = read(fd, &c, 1);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      problem = locus::Internal(what + ": " + std::strerror(errno));
      break;
    }
    if (n == 0 || c == '\n') break;
    if (line.size() >= kMaxAddress) {
      problem = locus::InvalidArgument(what + ": the address is longer than " +
                                       std::to_string(kMaxAddress) + " bytes");
      break;
    }
    line.push_back(c);
  }
  close(fd);
  if (!problem.ok()) return problem;
  if (line.empty()) {
    return locus::InvalidArgument(what + ": closed before an address came (the parent gave up)");
  }
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-worker: renders bands for a Locus coordinator"};
  locus::farm::WorkerOptions options;
  int poll_ms = 10000;
  // Required unless the `health` subcommand is given (checked below).
  app.add_option("--coordinator", options.coordinator, "Coordinator address, HOST:PORT");
  int coordinator_fd = -1;
  app.add_option("--coordinator-fd", coordinator_fd,
                 "Read the coordinator's address (one line) from this file descriptor, written "
                 "once it listens (`locus render`'s embedded farm starts its workers so)")
      ->check(CLI::Range(0, 1 << 20))
      ->excludes("--coordinator");
  app.add_option("--threads", options.threads,
                 "Threads per band (0 = all cores); run one worker per core by default")
      ->check(CLI::Range(0, 1024));
  app.add_option("--name", options.name, "Name shown by `locus workers` (default host:pid)");
  app.add_option("--tag", options.tags,
                 "A pool this worker is in (repeatable): jobs submitted with --require TAG go "
                 "only to workers carrying all their tags");
  app.add_option("--poll-ms", poll_ms, "Longest wait for a band per request")
      ->check(CLI::Range(100, 60000));
  double abandon_grace = 60;
  app.add_option("--abandon-grace", abandon_grace,
                 "Seconds a revoked band's render may take to stop before the worker exits (status "
                 "3) so that its supervisor restarts it")
      ->check(CLI::Range(0.0, 24 * 3600.0));
  int slow_band_ms = 0;
  app.add_option("--test-slow-band-ms", slow_band_ms,
                 "Test only: wait this long before rendering each band (a slow worker for the "
                 "fault tests)")
      ->check(CLI::Range(0, 600000));
  std::string token_file;
  locus::farm::Credentials& c = options.credentials;
  app.add_option("--token-file", token_file,
                 "File holding this worker's token (default: $LOCUS_TOKEN)");
  app.add_option("--tls-ca", c.tls_ca, "CA (PEM) that signed the coordinator's certificate");
  app.add_option("--tls-cert", c.tls_cert, "This worker's certificate (PEM), for mutual TLS");
  app.add_option("--tls-key", c.tls_key, "This worker's private key (PEM), for mutual TLS");
  app.add_flag("--insecure", c.insecure,
               "Plaintext to a non-loopback coordinator (a trusted network only)");
  app.add_option("--mesh-root", options.mesh_root,
                 "Directory of OBJ files scenes may name (default: none, meshes inline)");
  std::string health_address, metrics_address;
  std::string log_format = "text", log_level = "info";
  app.add_option("--health", health_address,
                 "Serve the gRPC health service, plaintext, on HOST:PORT (probes; ready while "
                 "registered with the coordinator)");
  app.add_option("--metrics", metrics_address,
                 "Serve Prometheus metrics at http://HOST:PORT/metrics");
  app.add_option("--log-format", log_format, "Log lines as text or json (one object per line)")
      ->check(CLI::IsMember(locus::label_names(locus::kLogFormatLabels)));
  app.add_option("--log-level", log_level, locus::label_choices(locus::kLogLevelLabels));
  std::string probe_address, probe_service;
  auto* health_cmd = app.add_subcommand(
      "health", "Ask a worker's (or coordinator's) gRPC health service, plaintext, and exit 0 when "
                "SERVING (probes); no worker runs");
  health_cmd->add_option("address", probe_address, "HOST:PORT of its --health port")->required();
  health_cmd->add_option("--service", probe_service,
                         "\"\" (default): ready; \"liveness\": the process runs");
  CLI11_PARSE(app, argc, argv);
  if (health_cmd->parsed()) return run_health(probe_address, probe_service);
  if (coordinator_fd >= 0) {
    auto address = read_address(coordinator_fd);
    if (!address.ok()) return fail(address.status().message());
    options.coordinator = *address;
  }
  if (options.coordinator.empty()) return fail("--coordinator is required");
  // Logs go to stderr: stdout carries what scripts read.
  if (auto st = locus::setup_logging(*locus::parse_log_format(log_format), log_level); !st.ok())
    return fail(st.message());
  options.poll = locus::farm::Millis(poll_ms);
  options.slow_band = locus::farm::Millis(slow_band_ms);
  options.abandon_grace =
      locus::farm::Millis(static_cast<int64_t>(std::llround(abandon_grace * 1000)));
  auto token = locus::farm::load_token(token_file);
  if (!token.ok()) return fail(token.status().message());
  c.token = *token;

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  locus::rpc::HealthServer health;
  if (!health_address.empty()) {
    auto port = health.start(health_address);
    if (!port.ok()) return fail(port.status().message());
    spdlog::info("health service on {} (port {})", health_address, *port);
    options.on_ready = [&health](bool ready) { health.set_ready(ready); };
  }
  locus::farm::WorkerClient worker(options);
  std::unique_ptr<locus::farm::MetricsEndpoint> metrics;
  if (!metrics_address.empty()) {
    auto m = locus::farm::MetricsEndpoint::start(metrics_address, worker.metrics().registry());
    if (!m.ok()) return fail(m.status().message());
    metrics = std::move(*m);
    spdlog::info("metrics on http://{}/metrics (port {})", metrics_address, metrics->port());
  }
  // The first signal: finish the band in hand (or hand it back if not yet
  // started), then exit. A second one: hand it back now and exit.
  // `acting` keeps the signals' actions and main's return apart: the hand
  // back makes run() return, and main returning then destroyed the worker
  // under the waiter (a crash, exit 139, as a Slurm job's time limit came
  // with its second SIGTERM). Main takes it after run() and never gives it
  // back; a waiter that holds it ends the process itself (_Exit).
  static std::mutex acting;
  std::thread waiter([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    {
      std::lock_guard lock(acting);
      spdlog::info("signal {}: finishing the band in hand, then exiting", sig);
      health.set_ready(false);
      worker.stop();
    }
    sigwait(&signals, &sig);
    acting.lock();
    spdlog::info("signal {} again: handing the band back and exiting now", sig);
    worker.hand_back();
    std::_Exit(0);
  });
  // The waiter may still sit in sigwait when main returns; exiting ends it.
  waiter.detach();
  const int code = worker.run();
  acting.lock();  // no signal acts on the worker from here: it is destroyed below
  return code;
}
