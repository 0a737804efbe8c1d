// locus-worker: a stateless render worker. It dials the coordinator, takes
// bands, renders them and returns the pixels until SIGTERM/SIGINT, after
// which it finishes the band in hand and exits.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <thread>

#include "worker/worker_client.h"

int main(int argc, char** argv) {
  CLI::App app{"locus-worker: renders bands for a Locus coordinator"};
  locus::farm::WorkerOptions options;
  int poll_ms = 10000;
  app.add_option("--coordinator", options.coordinator, "Coordinator address, HOST:PORT")
      ->required();
  app.add_option("--threads", options.threads,
                 "Threads per band (0 = all cores); run one worker per core by default")
      ->check(CLI::Range(0, 1024));
  app.add_option("--name", options.name, "Name shown by `locus workers` (default host:pid)");
  app.add_option("--poll-ms", poll_ms, "Longest wait for a band per request")
      ->check(CLI::Range(100, 60000));
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
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries what scripts read.
  spdlog::set_default_logger(spdlog::stderr_color_mt("locus"));
  options.poll = locus::farm::Millis(poll_ms);
  options.slow_band = locus::farm::Millis(slow_band_ms);
  auto token = locus::farm::load_token(token_file);
  if (!token.ok()) {
    std::fprintf(stderr, "locus-worker: %s\n", token.status().message().c_str());
    return 2;
  }
  c.token = *token;

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  locus::farm::WorkerClient worker(options);
  // The first signal: finish the band in hand (or hand it back if not yet
  // started), then exit. A second one: hand it back now and exit.
  std::thread waiter([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    spdlog::info("signal {}: finishing the band in hand, then exiting", sig);
    worker.stop();
    sigwait(&signals, &sig);
    spdlog::info("signal {} again: handing the band back and exiting now", sig);
    worker.hand_back();
    std::_Exit(0);
  });
  // The waiter may still sit in sigwait when run() returns; exiting ends it.
  waiter.detach();
  return worker.run();
}
