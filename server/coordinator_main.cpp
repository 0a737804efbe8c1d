// locus-coordinator: accepts jobs from `locus`, leases bands to the workers
// that dial in, stitches and writes the frames under its output root.
// Serves TLS with bearer tokens, or plaintext only with --insecure
// (docs/farm.md "Security"). main() runs the steps below in order: parse
// the flags, set up logging and security, start the coordinator, serve
// (the farm's port, then --health and --metrics), and on SIGINT or SIGTERM
// drain and shut down (docs/deploy.md "Stopping").
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <memory>

#include "common/base/log.h"
#include "common/farm/auth.h"
#include "server/backup.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"
#include "server/metrics.h"
#include "server/notifier.h"

namespace {

using locus::Result;
using locus::Status;
namespace farm = locus::farm;

int fail(const std::string& message) {
  std::fprintf(stderr, "locus-coordinator: %s\n", message.c_str());
  return 2;
}

// What the command line sets, with its defaults.
struct Flags {
  std::string listen = "127.0.0.1:7000";
  std::string data = "locus-data";
  int lease_ms = 5000;
  int heartbeat_ms = 1000;
  int attempts = 3;
  int quarantine_after = 2;
  double speculate_factor = 3.0;
  int speculate_min_ms = 1000;
  double band_timeout = 0;  // seconds
  double ageing = 60;       // seconds
  double retention_days = 0;
  bool no_fsync = false;
  bool no_exr_zip = false;
  int group_commit_ms = 5;
  int min_free_mb = 64;
  int frame_writers = 0;
  int handler_threads = 0;
  bool equal_bands = false;
  bool always_cost_bands = false;
  std::string health_address, metrics_address, http_address;
  double http_rate = 200;
  std::string log_format = "text", log_level = "info";
  int drain_ms = 20000;
  farm::CoordinatorOptions options;  // the flags that map one to one
  locus::rpc::ServerSecurity security;
  std::string client_tokens, worker_tokens, admin_tokens;
  std::string notify_cmd;
};

void add_farm_flags(CLI::App& app, Flags& f) {
  app.add_option("--listen", f.listen, "Address to serve on, HOST:PORT (port 0: any free port)");
  app.add_option("--data", f.data,
                 "Directory of the job store (locus.db) and the frames; a restart on the same "
                 "directory resumes its jobs");
  app.add_option("--output-root", f.options.output_root,
                 "Directory under which each job's frames are written, ROOT/<job>/ (default "
                 "DATA/jobs)");
  app.add_option("--mesh-root", f.options.mesh_root,
                 "Directory of OBJ files that submitted scenes may name (default: none, meshes "
                 "travel inline)");
  app.add_option("--lease-ms", f.lease_ms, "A band's lease lapses this long after its last renewal")
      ->check(CLI::Range(200, 3600000));
  app.add_option("--heartbeat-ms", f.heartbeat_ms, "Heartbeat period asked of workers")
      ->check(CLI::Range(50, 600000));
  app.add_option("--max-attempts,--attempts", f.attempts,
                 "Failed attempts (errors, lapsed leases) per band before its job fails")
      ->check(CLI::Range(1, 100));
  app.add_option("--quarantine-after", f.quarantine_after,
                 "Failures of one worker in a job after which it gets no more of that job's bands "
                 "while another worker can take them (0: never)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--handler-threads", f.handler_threads,
                 "Threads answering workers' calls (0: one per core, at least 4, at most 32; "
                 "-1: gRPC's own threads, as before)")
      ->check(CLI::Range(-1, 256));
  app.add_option("--frame-writers", f.frame_writers,
                 "Threads stitching and writing finished frames (0: one per core, at most 8)")
      ->check(CLI::Range(0, 64));
  app.add_option("--speculate-factor", f.speculate_factor,
                 "A band running this many times its job's median band time gets a second, "
                 "speculative lease (0: never)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--speculate-min-ms", f.speculate_min_ms,
                 "... and only once it has run at least this long")
      ->check(CLI::Range(0, 3600000));
  app.add_option("--band-timeout", f.band_timeout,
                 "Seconds a band may stay leased, however alive its worker, before it is taken "
                 "back as hung and retried elsewhere (a job's --band-timeout overrides; 0: never)")
      ->check(CLI::Range(0.0, 7 * 24 * 3600.0));
  app.add_option("--ageing", f.ageing,
                 "A job with bands waiting gains one priority point per this many seconds since "
                 "its last lease, so none starves (0: no ageing)")
      ->check(CLI::Range(0.0, 365 * 24 * 3600.0));
  app.add_option("--retention-days", f.retention_days,
                 "Finished jobs older than this many days are deleted with their frames, so the "
                 "data directory stays bounded (0: kept until `locus delete`)")
      ->check(CLI::Range(0.0, 36500.0));
  app.add_flag("--private-jobs", f.options.private_jobs,
               "A job's status, history and frames are its owner's and admins' only (default: "
               "every client reads every job)");
  app.add_option("--user-max-running", f.options.user_max_running,
                 "Most bands one user's jobs may run at once (0: no cap)")
      ->check(CLI::Range(0, 1000000));
  app.add_option("--notify-urls", f.options.notify_urls,
                 "URLs a job's --notify-url may fall under (same scheme, host and port, a path "
                 "below), comma-separated or repeated, e.g. https://hooks.studio.example/locus "
                 "(default: none; a job's end is then told to nobody)")
      ->delimiter(',');
  app.add_option("--notify-cmd", f.notify_cmd,
                 "A shell command run when any job ends, with LOCUS_JOB_ID, LOCUS_JOB_STATE, "
                 "LOCUS_JOB_KIND, LOCUS_JOB_OWNER, LOCUS_JOB_ERROR and LOCUS_JOB_DIR in its "
                 "environment (at most 60 s; its outcome in the job's history)");
  app.add_flag("--no-fsync", f.no_fsync,
               "Acknowledge bands without syncing the job store's log, and write frames without "
               "fsync (a crash of the coordinator is still survived; a power loss may cost "
               "acknowledged bands)");
  app.add_flag("--no-exr-zip", f.no_exr_zip,
               "EXR jobs' bands travel as float32+zstd (about 2.9x fewer bytes) and the "
               "coordinator compresses each frame (about 0.5 s of CPU a 1080p frame), instead of "
               "the workers compressing the frame's blocks");
  app.add_option("--group-commit-ms", f.group_commit_ms,
                 "Longest an accepted band waits for others to share its sync to disk (group "
                 "commit; default 5)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--min-free-mb", f.min_free_mb,
                 "Refuse new jobs while the data directory has less free space than this; after "
                 "its disk filled up, carry on once this much is free again (default 64)")
      ->check(CLI::Range(0, 1 << 20));
  app.add_flag("--equal-bands", f.equal_bands,
               "Cut frames into bands of equal height instead of equal predicted cost");
  app.add_flag("--always-cost-bands", f.always_cost_bands,
               "Cut by predicted cost even frames with 8 or more bands per worker (by default "
               "those get equal heights, sooner; the dashboard draws the prediction)")
      ->excludes("--equal-bands");
}

void add_security_flags(CLI::App& app, Flags& f) {
  locus::rpc::ServerSecurity& security = f.security;
  app.add_option("--tls-cert", security.tls_cert, "Server certificate chain (PEM)");
  app.add_option("--tls-key", security.tls_key, "Server certificate's private key (PEM)");
  app.add_option("--tls-ca", security.tls_ca,
                 "CA (PEM) for mutual TLS: workers must present a certificate it signed");
  app.add_option("--client-tokens", f.client_tokens,
                 "File of client tokens (submit, status, watch, cancel, fetch), one per line: "
                 "NAME TOKEN, or a token alone (its user is then token-LINE)");
  app.add_option("--admin-tokens", f.admin_tokens,
                 "File of admin tokens, NAME TOKEN per line: clients that may act on any "
                 "user's job");
  app.add_option("--worker-tokens", f.worker_tokens,
                 "File of worker tokens (take and return bands), one per line");
  app.add_flag("--insecure", security.insecure,
               "Allow serving without TLS, and without tokens (a trusted network only)");
}

// Operations (docs/deploy.md) and the limits every job is held to.
void add_operations_flags(CLI::App& app, Flags& f) {
  app.add_option("--health", f.health_address,
                 "Also serve the gRPC health service alone, plaintext, on HOST:PORT (probes)");
  app.add_option("--metrics", f.metrics_address,
                 "Serve Prometheus metrics at http://HOST:PORT/metrics");
  app.add_option("--http", f.http_address,
                 "Serve the dashboard and its JSON API on HOST:PORT (TLS when --tls-cert is "
                 "given; client tokens as for gRPC; docs/http-api.md)");
  app.add_option("--http-rate", f.http_rate,
                 "HTTP requests per second allowed from one address (past it: 429)")
      ->check(CLI::Range(1.0, 1e6));
  app.add_option("--drain-ms", f.drain_ms,
                 "On SIGTERM, wait this long at most for the bands in flight before exiting")
      ->check(CLI::Range(0, 3600000));
  app.add_option("--log-format", f.log_format, "Log lines as text or json (one object per line)")
      ->check(CLI::IsMember(locus::label_names(locus::kLogFormatLabels)));
  app.add_option("--log-level", f.log_level, locus::label_choices(locus::kLogLevelLabels));
  farm::Limits& limits = f.options.limits;
  app.add_option("--max-resolution", limits.max_resolution, "Largest image side, in pixels")
      ->check(CLI::Range(1, locus::kMaxResolution));
  app.add_option("--max-objects", limits.max_objects, "Most objects in a submitted scene")
      ->check(CLI::Range(1, 10000000));
  app.add_option("--max-frames", limits.max_frames, "Most frames per job")
      ->check(CLI::Range(1, farm::kMaxFramesPerJob));
  app.add_option("--max-bands", limits.max_bands, "Most bands per job (frames x bands)")
      ->check(CLI::Range(int64_t{1}, farm::kMaxBandsPerJob));
  app.add_option("--max-jobs", limits.max_jobs, "Most jobs queued or running at once")
      ->check(CLI::Range(1, 1000000));
}

// A worker renews its lease at least twice per lease.
Status check_lease_timing(const Flags& f) {
  if (f.heartbeat_ms * 2 > f.lease_ms) {
    return locus::InvalidArgument("--heartbeat-ms " + std::to_string(f.heartbeat_ms) +
                                  " must be at most half of --lease-ms " +
                                  std::to_string(f.lease_ms));
  }
  return Status::Ok();
}

// Token files read, then what the coordinator must refuse to start with;
// what --insecure lets through is said in the log.
Status set_up_security(Flags& f) {
  if (f.client_tokens.empty() != f.worker_tokens.empty())
    return locus::InvalidArgument(
        "--client-tokens and --worker-tokens go together (give both files)");
  if (!f.admin_tokens.empty() && f.client_tokens.empty())
    return locus::InvalidArgument("--admin-tokens needs --client-tokens and --worker-tokens");
  if (!f.client_tokens.empty()) {
    auto auth = farm::Authenticator::from_files(f.client_tokens, f.worker_tokens, f.admin_tokens);
    if (!auth.ok()) return auth.status();
    f.security.auth = std::move(*auth);
  }
  if (Status st = locus::rpc::check_server_security(f.security); !st.ok()) return st;
  if (f.security.tls_cert.empty())
    spdlog::warn("--insecure: serving plaintext; anyone on the path can read the traffic");
  if (!f.security.auth.enforcing())
    spdlog::warn("--insecure: no tokens; anyone who reaches {} can use the farm", f.listen);
  return Status::Ok();
}

farm::CoordinatorOptions coordinator_options(const Flags& f) {
  farm::CoordinatorOptions options = f.options;
  options.data_dir = f.data;
  options.lease = farm::Millis(f.lease_ms);
  options.heartbeat = farm::Millis(f.heartbeat_ms);
  options.max_attempts = f.attempts;
  options.quarantine_after = f.quarantine_after;
  options.speculate_factor = f.speculate_factor;
  options.speculate_min = farm::Millis(f.speculate_min_ms);
  options.band_timeout = farm::Millis(static_cast<int64_t>(std::llround(f.band_timeout * 1000)));
  options.ageing = farm::Millis(static_cast<int64_t>(std::llround(f.ageing * 1000)));
  options.retention =
      farm::Millis(static_cast<int64_t>(std::llround(f.retention_days * 86400.0 * 1000)));
  options.fsync = !f.no_fsync;
  options.exr_zip = !f.no_exr_zip;
  options.group_commit = farm::Millis(f.group_commit_ms);
  options.frame_writers = f.frame_writers;
  options.handler_threads = f.handler_threads;
  options.min_free_bytes = static_cast<uint64_t>(f.min_free_mb) << 20;
  options.cost_bands = !f.equal_bands;
  options.always_cost_bands = f.always_cost_bands;
  return options;
}

// Each connected worker holds a connection (a file descriptor): the soft
// limit on open files (1024 on most systems) is raised to the hard one, so
// that a farm of thousands of workers is not refused at the 1024th.
void raise_open_files_limit() {
  rlimit r{};
  if (::getrlimit(RLIMIT_NOFILE, &r) != 0 || r.rlim_cur >= r.rlim_max) return;
  const rlim_t was = r.rlim_cur;
  r.rlim_cur = r.rlim_max;
  if (::setrlimit(RLIMIT_NOFILE, &r) == 0)
    spdlog::debug("open files: limit raised from {} to {}", was, r.rlim_cur);
}

// Signals are taken synchronously by the main thread (drain_on_signal);
// blocked before gRPC starts its threads so none of those gets them.
sigset_t block_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

// The farm's port; the security goes to the server.
Status serve_farm(locus::rpc::CoordinatorServer& server, farm::Coordinator& coordinator, Flags& f) {
  const bool tls = !f.security.tls_cert.empty();
  const bool mtls = !f.security.tls_ca.empty();
  const bool tokens = f.security.auth.enforcing();
  auto port = server.start(f.listen, f.security);
  if (!port.ok()) return port.status();
  spdlog::info("locus-coordinator listening on {} (port {}; {}{}, {}), frames in {}", f.listen,
               *port, tls ? "TLS" : "plaintext", mtls ? " with worker certificates" : "",
               tokens ? "tokens required" : "no tokens", coordinator.output_root());
  // Scripts that start it on port 0 read the port from stdout.
  std::printf("listening on port %d\n", *port);
  std::fflush(stdout);
  return Status::Ok();
}

// --health and --metrics, when asked for; the metrics endpoint lives as
// long as the returned pointer.
Result<std::unique_ptr<farm::MetricsEndpoint>> serve_operations(
    locus::rpc::CoordinatorServer& server, farm::Coordinator& coordinator, const Flags& f) {
  if (!f.health_address.empty()) {
    auto health_port = server.serve_health(f.health_address);
    if (!health_port.ok()) return health_port.status();
    spdlog::info("health service on {} (port {})", f.health_address, *health_port);
  }
  if (!f.http_address.empty()) {
    locus::rpc::HttpServerOptions o;
    o.address = f.http_address;
    locus::rpc::HttpOptions api;
    api.rate = f.http_rate;
    api.burst = 2 * f.http_rate;
    auto port = server.serve_http(o, api);
    if (!port.ok()) return port.status();
    spdlog::info("dashboard on {}://{} (port {})", f.security.tls_cert.empty() ? "http" : "https",
                 f.http_address, *port);
    std::printf("dashboard on port %d\n", *port);
    std::fflush(stdout);
  }
  std::unique_ptr<farm::MetricsEndpoint> metrics;
  if (!f.metrics_address.empty()) {
    auto m = farm::MetricsEndpoint::start(f.metrics_address, coordinator.metrics().registry(),
                                          [&coordinator] { coordinator.refresh_metrics(); });
    if (!m.ok()) return m.status();
    metrics = std::move(*m);
    spdlog::info("metrics on http://{}/metrics (port {})", f.metrics_address, metrics->port());
  }
  return metrics;
}

// Waits for SIGINT or SIGTERM, then drains: no new jobs or leases, the
// bands in flight given up to --drain-ms, then shutdown.
void drain_on_signal(locus::rpc::CoordinatorServer& server, const sigset_t& signals, int drain_ms) {
  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: draining, then shutting down", sig);
  server.drain(farm::Millis(drain_ms), farm::Millis(2000));
  spdlog::info("stopped");
}

// `backup OUT`: the data directory copied while a coordinator may run on it
// (server/backup.h); what it took on stdout.
int run_backup(const Flags& f, const std::string& out) {
  farm::BackupOptions o;
  o.data_dir = f.data;
  o.output_root = f.options.output_root;
  o.out = out;
  auto r = farm::backup_data_dir(o);
  if (!r.ok()) return fail(r.status().message());
  for (const std::string& band : r->rendered_again)
    spdlog::warn(
        "{}: accepted during the backup, its frame written since; rendered again on restore", band);
  std::printf(
      "backup %s: %d jobs, %lld store pages, %d band files, %d frame files (%d linked, %d "
      "copied); restore with locus-coordinator --data %s\n",
      out.c_str(), r->jobs, static_cast<long long>(r->pages), r->band_files, r->job_files,
      r->linked, r->copied, out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-coordinator: the Locus render farm's coordinator"};
  Flags f;
  add_farm_flags(app, f);
  add_security_flags(app, f);
  add_operations_flags(app, f);
  std::string backup_out;
  CLI::App* backup = app.add_subcommand(
      "backup",
      "Copy the job store (--data) and its jobs' band and frame files (--output-root) into OUT "
      "while the coordinator runs, then exit; restore: locus-coordinator --data OUT");
  backup->add_option("OUT", backup_out, "A new directory for the backup")->required();
  backup->fallthrough();  // --data and --output-root also after OUT
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr: stdout carries what scripts read.
  if (auto st = locus::setup_logging(*locus::parse_log_format(f.log_format), f.log_level); !st.ok())
    return fail(st.message());
  if (*backup) return run_backup(f, backup_out);
  if (Status st = check_lease_timing(f); !st.ok()) return fail(st.message());
  if (Status st = set_up_security(f); !st.ok()) return fail(st.message());
  const sigset_t signals = block_signals();
  raise_open_files_limit();

  farm::Coordinator coordinator(coordinator_options(f));
  // Before start(): it tells the ends a stop left untold.
  locus::rpc::NotifierOptions notify;
  notify.command = f.notify_cmd;
  locus::rpc::Notifier notifier(coordinator, notify);
  if (Status st = coordinator.start(); !st.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", st.message().c_str());
    return 1;
  }
  locus::rpc::CoordinatorServer server(coordinator);
  if (Status st = serve_farm(server, coordinator, f); !st.ok()) {
    std::fprintf(stderr, "locus-coordinator: %s\n", st.message().c_str());
    return 1;
  }
  auto metrics = serve_operations(server, coordinator, f);
  if (!metrics.ok()) return fail(metrics.status().message());

  drain_on_signal(server, signals, f.drain_ms);
  return 0;
}
