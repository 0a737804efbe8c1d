// The CLI's side of ClientService: every call with a deadline, every error
// a locus::Status whose message names the farm and the fix.
#pragma once

#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/farm/auth.h"
#include "common/farm/types.h"

namespace locus::v1 {
class ClientService;
}

namespace locus::client {

// A submission travels in one gRPC message of at most
// farm::kMaxMessageBytes, nearly all of it the scene: a larger one is
// refused here (kResourceExhausted, naming the scene and its size; the
// caller adds what to do) rather than by gRPC. FarmClient::submit checks
// it; `locus render` asks first, to render in process instead.
Status check_submission_size(const farm::SubmitRequest& request);

// Where fetched files go (FarmClient::fetch, LocalFarm::fetch): a frame's
// file name from the coordinator to the client's path.
using FileDest = std::function<std::string(int frame, const std::string& file_name)>;

// Writes the chunks of fetched files, in the order a coordinator sends them
// (Coordinator::fetch), each file to dest(frame, name) through a
// ".partial" beside it, renamed once whole. `peer` names the sender in its
// errors. The first failure stops it (take() returns false) and is
// status(); a writer destroyed with a file half written removes it.
class FetchedFiles {
 public:
  FetchedFiles(FileDest dest, std::string peer) : dest_(std::move(dest)), peer_(std::move(peer)) {}
  ~FetchedFiles();
  bool take(const farm::FileChunk& chunk);
  const Status& status() const { return status_; }
  // The files written whole, in order.
  const std::vector<std::string>& written() const { return written_; }

 private:
  bool failed(Status s);
  FileDest dest_;
  std::string peer_;
  Status status_ = Status::Ok();
  std::vector<std::string> written_;
  std::ofstream out_;
  std::string path_, tmp_;
  int64_t expected_ = 0;
};

class FarmClient {
 public:
  // A bad credential (unreadable --tls-ca, plaintext to a remote address
  // without --insecure) is returned by every call.
  explicit FarmClient(const std::string& address, const farm::Credentials& credentials = {});
  ~FarmClient();

  Result<farm::JobInfo> submit(const farm::SubmitRequest& request);
  Result<farm::JobInfo> job(const std::string& job_id);
  Result<std::vector<farm::JobInfo>> jobs();
  Result<farm::JobInfo> cancel(const std::string& job_id);
  Result<farm::JobInfo> set_priority(const std::string& job_id, int priority, bool preempt);
  Result<farm::JobInfo> pause(const std::string& job_id);
  Result<farm::JobInfo> resume(const std::string& job_id);
  // A failed or cancelled job back in the queue, with fresh attempts.
  Result<farm::JobInfo> retry(const std::string& job_id);
  // The written frames in [first, last] (absent: the job's bounds) again.
  Result<farm::JobInfo> requeue(const std::string& job_id, std::optional<int> first,
                                std::optional<int> last);
  // A finished job; `outputs`: its frames too. Its last status.
  Result<farm::JobInfo> remove(const std::string& job_id, bool outputs);
  // The lines workers logged for the job's bands after cursor `after`, of
  // one frame and band (-1: any).
  Result<std::vector<farm::BandLogLine>> logs(const std::string& job_id, int frame, int band,
                                              int64_t after);
  // The job's history after cursor `after` (all of it from 0).
  Result<std::vector<farm::HistoryEntry>> events(const std::string& job_id, int64_t after);
  Result<std::vector<farm::WorkerInfo>> workers();
  // Admins only; `worker` is an id or a name. Returns the worker's name.
  Result<std::string> drain_worker(const std::string& worker);
  Result<std::string> disable_worker(const std::string& worker);
  Result<std::string> enable_worker(const std::string& worker);
  // Follows the job until it ends (re-opening the stream as the server caps
  // its length); `on_update` sees every status. Returns the final status.
  Result<farm::JobInfo> watch(const std::string& job_id,
                              const std::function<void(const farm::JobInfo&)>& on_update);
  // Fetches written frames (`frames` empty: all written so far); each file
  // goes to dest(frame, file_name), written atomically. Returns the paths.
  // A file name from the coordinator that is not a plain file name is
  // refused before `dest` sees it. `cost_maps`: the frames' cost maps
  // instead (a job submitted with one).
  Result<std::vector<std::string>> fetch(const std::string& job_id, const std::vector<int>& frames,
                                         const FileDest& dest, bool cost_maps = false);

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace locus::client
