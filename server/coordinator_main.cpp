// locus-coordinator: accepts jobs from `locus`, leases bands to the workers
// that dial in, stitches and writes the frames under --data.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>

#include "server/coordinator.h"
#include "server/grpc_service.h"

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
  app.add_option("--listen", listen, "Address to serve on, HOST:PORT (port 0: any free port)");
  app.add_option("--data", data,
                 "Directory of the job store (locus.db) and the frames; a restart on the same "
                 "directory resumes its jobs");
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
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries what scripts read.
  spdlog::set_default_logger(spdlog::stderr_color_mt("locus"));
  if (heartbeat_ms * 2 > lease_ms) {
    std::fprintf(stderr,
                 "locus-coordinator: --heartbeat-ms %d must be at most half of --lease-ms %d\n",
                 heartbeat_ms, lease_ms);
    return 2;
  }

  // Signals are taken synchronously by the main thread below; block them
  // before gRPC starts its threads so none of those gets them.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  locus::farm::CoordinatorOptions options;
  options.data_dir = data;
  options.lease = locus::farm::Millis(lease_ms);
  options.heartbeat = locus::farm::Millis(heartbeat_ms);
  options.max_attempts = attempts;
  options.quarantine_after = quarantine_after;
  options.speculate_factor = speculate_factor;
  options.speculate_min = locus::farm::Millis(speculate_min_ms);
  options.fsync = !no_fsync;
  locus::farm::Coordinator coordinator(options);
  if (auto st = coordinator.start(); !st.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", st.message().c_str());
    return 1;
  }
  locus::rpc::CoordinatorServer server(coordinator);
  auto port = server.start(listen);
  if (!port.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", port.status().message().c_str());
    return 1;
  }
  spdlog::info("locus-coordinator listening on {} (port {}), data in {}", listen, *port, data);
  // Scripts that start it on port 0 read the port from stdout.
  std::printf("listening on port %d\n", *port);
  std::fflush(stdout);

  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: shutting down", sig);
  server.shutdown(locus::farm::Millis(2000));
  return 0;
}
