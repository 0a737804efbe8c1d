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
  app.add_option("--listen", listen, "Address to serve on, HOST:PORT (port 0: any free port)");
  app.add_option("--data", data, "Directory for the written frames");
  app.add_option("--lease-ms", lease_ms, "A band's lease lapses this long after its last renewal")
      ->check(CLI::Range(200, 3600000));
  app.add_option("--heartbeat-ms", heartbeat_ms, "Heartbeat period asked of workers")
      ->check(CLI::Range(50, 600000));
  app.add_option("--attempts", attempts, "Leases per band before its job fails")
      ->check(CLI::Range(1, 100));
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
