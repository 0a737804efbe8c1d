// locus-coordinator: accepts jobs from `locus`, leases bands to the workers
// that dial in, stitches and writes the frames under its output root.
// Serves TLS with bearer tokens, or plaintext only with --insecure
// (docs/farm.md "Security").
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>

#include "common/base/log.h"
#include "common/farm/auth.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"
#include "server/metrics.h"

namespace {

int fail(const std::string& message) {
  std::fprintf(stderr, "locus-coordinator: %s\n", message.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-coordinator: the Locus render farm's coordinator"};
  std::string listen = "127.0.0.1:7000";
  std::string data = "locus-data";
  int lease_ms = 5000;
  int heartbeat_ms = 1000;
  int attempts = 3;
  int quarantine_after = 2;
  double speculate_factor = 3.0;
  int speculate_min_ms = 1000;
  bool no_fsync = false;
  bool equal_bands = false;
  std::string health_address, metrics_address;
  std::string log_format = "text", log_level = "info";
  int drain_ms = 20000;
  locus::farm::CoordinatorOptions options;
  locus::farm::Limits& limits = options.limits;
  locus::rpc::ServerSecurity security;
  std::string client_tokens, worker_tokens;
  app.add_option("--listen", listen, "Address to serve on, HOST:PORT (port 0: any free port)");
  app.add_option("--data", data,
                 "Directory of the job store (locus.db) and the frames; a restart on the same "
                 "directory resumes its jobs");
  app.add_option("--output-root", options.output_root,
                 "Directory under which each job's frames are written, ROOT/<job>/ (default "
                 "DATA/jobs)");
  app.add_option("--mesh-root", options.mesh_root,
                 "Directory of OBJ files that submitted scenes may name (default: none, meshes "
                 "travel inline)");
  app.add_option("--lease-ms", lease_ms, "A band's lease lapses this long after its last renewal")
      ->check(CLI::Range(200, 3600000));
  app.add_option("--heartbeat-ms", heartbeat_ms, "Heartbeat period asked of workers")
      ->check(CLI::Range(50, 600000));
  app.add_option("--max-attempts,--attempts", attempts,
                 "Failed attempts (errors, lapsed leases) per band before its job fails")
      ->check(CLI::Range(1, 100));
  app.add_option("--quarantine-after", quarantine_after,
                 "Failures of one worker in a job after which it gets no more of that job's bands "
                 "while another worker can take them (0: never)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--speculate-factor", speculate_factor,
                 "A band running this many times its job's median band time gets a second, "
                 "speculative lease (0: never)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--speculate-min-ms", speculate_min_ms,
                 "... and only once it has run at least this long")
      ->check(CLI::Range(0, 3600000));
  app.add_flag("--no-fsync", no_fsync,
               "Do not fsync band and frame files (faster; a crash of the coordinator is still "
               "survived, a power loss may cost finished bands)");
  app.add_flag("--equal-bands", equal_bands,
               "Cut frames into bands of equal height instead of equal predicted cost");
  // Security.
  app.add_option("--tls-cert", security.tls_cert, "Server certificate chain (PEM)");
  app.add_option("--tls-key", security.tls_key, "Server certificate's private key (PEM)");
  app.add_option("--tls-ca", security.tls_ca,
                 "CA (PEM) for mutual TLS: workers must present a certificate it signed");
  app.add_option("--client-tokens", client_tokens,
                 "File of client tokens (submit, status, watch, cancel, fetch), one per line");
  app.add_option("--worker-tokens", worker_tokens,
                 "File of worker tokens (take and return bands), one per line");
  app.add_flag("--insecure", security.insecure,
               "Allow serving without TLS, and without tokens (a trusted network only)");
  // Operations (docs/deploy.md).
  app.add_option("--health", health_address,
                 "Also serve the gRPC health service alone, plaintext, on HOST:PORT (probes)");
  app.add_option("--metrics", metrics_address,
                 "Serve Prometheus metrics at http://HOST:PORT/metrics");
  app.add_option("--drain-ms", drain_ms,
                 "On SIGTERM, wait this long at most for the bands in flight before exiting")
      ->check(CLI::Range(0, 3600000));
  app.add_option("--log-format", log_format, "Log lines as text or json (one object per line)")
      ->check(CLI::IsMember({"text", "json"}));
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical or off");
  // Limits.
  app.add_option("--max-resolution", limits.max_resolution, "Largest image side, in pixels")
      ->check(CLI::Range(1, locus::kMaxResolution));
  app.add_option("--max-objects", limits.max_objects, "Most objects in a submitted scene")
      ->check(CLI::Range(1, 10000000));
  app.add_option("--max-frames", limits.max_frames, "Most frames per job")
      ->check(CLI::Range(1, locus::farm::kMaxFramesPerJob));
  app.add_option("--max-bands", limits.max_bands, "Most bands per job (frames x bands)")
      ->check(CLI::Range(int64_t{1}, locus::farm::kMaxBandsPerJob));
  app.add_option("--max-jobs", limits.max_jobs, "Most jobs queued or running at once")
      ->check(CLI::Range(1, 1000000));
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries what scripts read.
  if (auto st = locus::setup_logging(*locus::parse_log_format(log_format), log_level); !st.ok())
    return fail(st.message());
  if (heartbeat_ms * 2 > lease_ms) {
    return fail("--heartbeat-ms " + std::to_string(heartbeat_ms) +
                " must be at most half of --lease-ms " + std::to_string(lease_ms));
  }
  if (client_tokens.empty() != worker_tokens.empty())
    return fail("--client-tokens and --worker-tokens go together (give both files)");
  if (!client_tokens.empty()) {
    auto auth = locus::farm::Authenticator::from_files(client_tokens, worker_tokens);
    if (!auth.ok()) return fail(auth.status().message());
    security.auth = std::move(*auth);
  }
  if (locus::Status st = locus::rpc::check_server_security(security); !st.ok()) return fail(st.message());
  if (security.tls_cert.empty())
    spdlog::warn("--insecure: serving plaintext; anyone on the path can read the traffic");
  if (!security.auth.enforcing())
    spdlog::warn("--insecure: no tokens; anyone who reaches {} can use the farm", listen);

  // Signals are taken synchronously by the main thread below; block them
  // before gRPC starts its threads so none of those gets them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  options.data_dir = data;
  options.lease = locus::farm::Millis(lease_ms);
  options.heartbeat = locus::farm::Millis(heartbeat_ms);
  options.max_attempts = attempts;
  options.quarantine_after = quarantine_after;
  options.speculate_factor = speculate_factor;
  options.speculate_min = locus::farm::Millis(speculate_min_ms);
  options.fsync = !no_fsync;
  options.cost_bands = !equal_bands;
  locus::farm::Coordinator coordinator(options);
  if (auto st = coordinator.start(); !st.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", st.message().c_str());
    return 1;
  }
  const bool tls = !security.tls_cert.empty();
  const bool mtls = !security.tls_ca.empty();
  const bool tokens = security.auth.enforcing();
  locus::rpc::CoordinatorServer server(coordinator);
  auto port = server.start(listen, std::move(security));
  if (!port.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", port.status().message().c_str());
    return 1;
  }
  spdlog::info("locus-coordinator listening on {} (port {}; {}{}, {}), frames in {}", listen,
               *port, tls ? "TLS" : "plaintext", mtls ? " with worker certificates" : "",
               tokens ? "tokens required" : "no tokens", coordinator.output_root());
  // Scripts that start it on port 0 read the port from stdout.
  std::printf("listening on port %d\n", *port);
  std::fflush(stdout);
  if (!health_address.empty()) {
    auto health_port = server.serve_health(health_address);
    if (!health_port.ok()) return fail(health_port.status().message());
    spdlog::info("health service on {} (port {})", health_address, *health_port);
  }
  std::unique_ptr<locus::farm::MetricsEndpoint> metrics;
  if (!metrics_address.empty()) {
    auto m = locus::farm::MetricsEndpoint::start(metrics_address, coordinator.metrics().registry(),
                                                 [&coordinator] { coordinator.refresh_metrics(); });
    if (!m.ok()) return fail(m.status().message());
    metrics = std::move(*m);
    spdlog::info("metrics on http://{}/metrics (port {})", metrics_address, metrics->port());
  }

  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: draining, then shutting down", sig);
  server.drain(locus::farm::Millis(drain_ms), locus::farm::Millis(2000));
  spdlog::info("stopped");
  return 0;
}
