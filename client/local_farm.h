// The embedded farm of `locus render --workers N`: a coordinator inside this
// process on 127.0.0.1 (ephemeral port) and N `locus-worker` processes found
// next to the `locus` binary, started first and given the coordinator's
// address on a socket once it listens (docs/farm.md "Start and end of the
// embedded farm"). The job then runs through the same gRPC path as on a
// real farm, under a random token that the workers get through LOCUS_TOKEN
// in their environment.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "client/farm_client.h"
#include "common/base/status.h"
#include "server/coordinator.h"
#include "server/grpc_service.h"

namespace locus::client {

struct LocalFarmOptions {
  int workers = 2;
  int threads = 1;  // per worker
  farm::Millis lease{5000};
  bool dashboard = true;  // serve the dashboard on 127.0.0.1 (any free port)
};

// Whether the farm's EXR jobs lease exr+zip (workers compress their bands'
// blocks): only when its `workers` of `threads` each (0: every core) fill
// the machine's `cores`. A worker that leaves a core idle (one on two
// cores) renders EXR frames sooner if the coordinator compresses each frame
// on every core (write_exr) than if it compresses its bands' blocks alone
// (docs/farm.md "Frames").
bool local_farm_zips_exr(int workers, int threads, int cores);

class LocalFarm {
 public:
  // Starts the coordinator and the workers. The workers load and register
  // while the caller goes on (reading the scene); wait_for_workers() then
  // waits (briefly) until they have.
  static Result<std::unique_ptr<LocalFarm>> start(const LocalFarmOptions& options);
  Status wait_for_workers();
  ~LocalFarm();  // SIGTERM to the workers (SIGKILL if they linger), then the server

  const std::string& address() const { return address_; }
  // The farm's random token (both roles), for this process's client.
  const std::string& token() const { return token_; }
  // The dashboard's address with the token in its fragment (the browser
  // keeps it in the tab and never sends it in a URL); empty: none.
  const std::string& dashboard_url() const { return dashboard_url_; }
  // The directory of worker logs (worker-N.log); kept when keep_logs() was
  // called, or when workers died.
  const std::string& dir() const { return dir_; }
  void keep_logs() { keep_ = true; }
  // Submits a job of this process's own: a call on the coordinator, as the
  // farm's one user (kUser, the token's), not a SubmitJob over the
  // loopback. The gRPC path serialized the scene, sent it, parsed it and
  // copied it once more: 60-90 ms before a big scene's job existed (SPD
  // tetra level 8, 5 MB; docs/farm.md "Start and end of the embedded
  // farm"). The job is then followed and fetched over gRPC like any.
  Result<farm::JobInfo> submit(const farm::SubmitRequest& request);
  // A job's written frames (or cost maps), every one, by a call too: the
  // coordinator's own chunks into FetchedFiles, as FarmClient::fetch writes
  // them, without the loopback's copies (7-14 ms of a 512x512 EXR's).
  Result<std::vector<std::string>> fetch(const std::string& job_id, const FileDest& dest,
                                         bool cost_maps = false);
  static constexpr const char* kUser = "local";

  // Ends this process once its job's files are written: the workers ended
  // (end_workers), the temporary directory removed, stdio and the log
  // flushed, then std::_Exit(code). The coordinator, its server and
  // their threads are left to the exit: none holds anything the command
  // still needs (the job's frames are fetched), and shutting each down in
  // order cost `locus render --workers N` some 10-17 ms.
  [[noreturn]] void exit_process(int code);

 private:
  LocalFarm() = default;
  // Reaps workers that exit on their own; when none is left, cancels every
  // job, so that a client waiting on one learns of it instead of hanging.
  void monitor();
  // Stops the monitor, then ends the workers and reaps them: SIGKILL, or
  // where the logs are kept SIGTERM and SIGKILL after 3 s. Both ways out
  // use it.
  void end_workers();
  // The temporary directory, unless its logs are kept; last, once nothing
  // writes there any more.
  void remove_dir();

  std::string dir_;
  std::string address_;
  std::string token_;
  std::string dashboard_url_;
  std::unique_ptr<farm::Coordinator> coordinator_;
  std::unique_ptr<rpc::CoordinatorServer> server_;
  int workers_ = 0;  // started
  std::mutex mu_;
  std::condition_variable stop_;  // wakes the monitor at once
  std::vector<pid_t> pids_;  // running workers
  std::atomic<bool> stopping_{false};
  std::thread monitor_;
  bool keep_ = false;
};

// The `locus-worker` beside the running `locus`, or NotFound.
Result<std::string> worker_binary();

}  // namespace locus::client
