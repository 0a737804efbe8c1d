#include "client/farm_client.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "common/farm/paths.h"
#include "proto/wire/rpc.h"

namespace locus::client {
namespace fs = std::filesystem;
namespace {

// How long a watch that lost its farm waits for it (a coordinator's
// restart), and how long a submission is retried.
constexpr farm::Millis kRetryFor{60000};
constexpr farm::Millis kSubmitRetryFor{10000};

bool transient(const Status& s) {
  return s.code() == Code::kUnavailable || s.code() == Code::kDeadlineExceeded;
}

std::string new_request_id() {
  std::random_device rd;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%08x%08x%08x%08x", rd(), rd(), rd(), rd());
  return buf;
}

}  // namespace

Status check_submission_size(const farm::SubmitRequest& request) {
  // The job's other fields: far below this.
  constexpr size_t kRoom = 1 << 20;
  const size_t bytes = request.scene.ByteSizeLong();
  if (bytes + kRoom <= static_cast<size_t>(farm::kMaxMessageBytes)) return Status::Ok();
  char what[256];
  std::snprintf(what, sizeof what,
                "%s: the scene is %.1f MiB as a farm job (%d objects); a job is sent in one "
                "message of at most %d MiB",
                request.scene_name.empty() ? "the job" : request.scene_name.c_str(),
                bytes / 1048576.0, request.scene.objects_size(),
                (farm::kMaxMessageBytes - static_cast<int>(kRoom)) >> 20);
  return Status(Code::kResourceExhausted, what);
}

class FarmClient::Impl {
 public:
  Impl(const std::string& address, const farm::Credentials& credentials)
      : peer("farm at " + address) {
    auto c = rpc::connect(address, credentials);
    if (!c.ok()) {
      broken = c.status();
      return;
    }
    conn = std::move(*c);
    stub = v1::ClientService::NewStub(conn.channel);
  }
  rpc::Connection conn;
  std::unique_ptr<v1::ClientService::Stub> stub;
  std::string peer;
  Status broken;

  Status check(const grpc::Status& s) const { return rpc::FromGrpc(s, peer); }
  // A short unary call to an action on a job: the job's status after it.
  template <class Request>
  Result<farm::JobInfo> action(grpc::Status (v1::ClientService::Stub::*method)(
                                   grpc::ClientContext*, const Request&, v1::JobActionResponse*),
                               const Request& req) const {
    if (!broken.ok()) return broken;
    v1::JobActionResponse resp;
    grpc::ClientContext ctx;
    prepare(ctx, rpc::kShortCall);
    if (Status s = check((stub.get()->*method)(&ctx, req, &resp)); !s.ok()) return s;
    return rpc::FromProto(resp.status());
  }
  // The same for an action on a worker: its name.
  Result<std::string> worker_action(grpc::Status (v1::ClientService::Stub::*method)(
                                        grpc::ClientContext*, const v1::WorkerActionRequest&,
                                        v1::WorkerActionResponse*),
                                    const std::string& worker) const {
    if (!broken.ok()) return broken;
    v1::WorkerActionRequest req;
    req.set_worker(worker);
    v1::WorkerActionResponse resp;
    grpc::ClientContext ctx;
    prepare(ctx, rpc::kShortCall);
    if (Status s = check((stub.get()->*method)(&ctx, req, &resp)); !s.ok()) return s;
    return resp.worker_name();
  }
  void prepare(grpc::ClientContext& ctx, farm::Millis timeout) const {
    rpc::prepare(ctx, conn, timeout);
  }
};

FarmClient::FarmClient(const std::string& address, const farm::Credentials& credentials)
    : impl_(std::make_unique<Impl>(address, credentials)) {}
FarmClient::~FarmClient() = default;

Result<farm::JobInfo> FarmClient::submit(const farm::SubmitRequest& request) {
  if (!impl_->broken.ok()) return impl_->broken;
  if (Status s = check_submission_size(request); !s.ok()) {
    return Status(s.code(), s.message() +
                                ": split the scene, or render it in process (locus "
                                "render --workers 0)");
  }
  v1::SubmitJobRequest req;
  *req.mutable_spec() = rpc::ToProto(request);
  // One id per submission, the same on every retry: the coordinator then
  // creates the job once however many of the attempts reached it.
  req.set_request_id(request.request_id.empty() ? new_request_id() : request.request_id);
  const auto give_up = std::chrono::steady_clock::now() + kSubmitRetryFor;
  farm::Millis backoff{250};
  for (;;) {
    v1::SubmitJobResponse resp;
    grpc::ClientContext ctx;
    impl_->prepare(ctx, rpc::kDataCall);
    const Status s = impl_->check(impl_->stub->SubmitJob(&ctx, req, &resp));
    if (s.ok()) return rpc::FromProto(resp.status());
    if (!transient(s) || std::chrono::steady_clock::now() + backoff > give_up) return s;
    std::this_thread::sleep_for(backoff);
    backoff = std::min(backoff * 2, farm::Millis(1000));
  }
}

Result<farm::JobInfo> FarmClient::job(const std::string& job_id) {
  if (!impl_->broken.ok()) return impl_->broken;
  v1::GetJobRequest req;
  req.set_job_id(job_id);
  v1::JobStatus resp;
  grpc::ClientContext ctx;
  impl_->prepare(ctx, rpc::kShortCall);
  if (Status s = impl_->check(impl_->stub->GetJob(&ctx, req, &resp)); !s.ok()) return s;
  return rpc::FromProto(resp);
}

Result<std::vector<farm::JobInfo>> FarmClient::jobs() {
  if (!impl_->broken.ok()) return impl_->broken;
  v1::ListJobsResponse resp;
  grpc::ClientContext ctx;
  impl_->prepare(ctx, rpc::kShortCall);
  if (Status s = impl_->check(impl_->stub->ListJobs(&ctx, v1::ListJobsRequest(), &resp)); !s.ok())
    return s;
  std::vector<farm::JobInfo> out;
  for (const v1::JobStatus& j : resp.jobs()) out.push_back(rpc::FromProto(j));
  return out;
}

Result<farm::JobInfo> FarmClient::cancel(const std::string& job_id) {
  if (!impl_->broken.ok()) return impl_->broken;
  v1::CancelJobRequest req;
  req.set_job_id(job_id);
  v1::CancelJobResponse resp;
  grpc::ClientContext ctx;
  impl_->prepare(ctx, rpc::kShortCall);
  if (Status s = impl_->check(impl_->stub->CancelJob(&ctx, req, &resp)); !s.ok()) return s;
  return rpc::FromProto(resp.status());
}

Result<farm::JobInfo> FarmClient::set_priority(const std::string& job_id, int priority,
                                               bool preempt) {
  v1::SetPriorityRequest req;
  req.set_job_id(job_id);
  req.set_priority(priority);
  req.set_preempt(preempt);
  return impl_->action(&v1::ClientService::Stub::SetPriority, req);
}

Result<farm::JobInfo> FarmClient::pause(const std::string& job_id) {
  v1::JobActionRequest req;
  req.set_job_id(job_id);
  return impl_->action(&v1::ClientService::Stub::PauseJob, req);
}

Result<farm::JobInfo> FarmClient::resume(const std::string& job_id) {
  v1::JobActionRequest req;
  req.set_job_id(job_id);
  return impl_->action(&v1::ClientService::Stub::ResumeJob, req);
}

Result<farm::JobInfo> FarmClient::retry(const std::string& job_id) {
  v1::JobActionRequest req;
  req.set_job_id(job_id);
  return impl_->action(&v1::ClientService::Stub::RetryJob, req);
}

Result<farm::JobInfo> FarmClient::requeue(const std::string& job_id, std::optional<int> first,
                                          std::optional<int> last) {
  v1::RequeueJobRequest req;
  req.set_job_id(job_id);
  if (first) req.set_frame_first(*first);
  if (last) req.set_frame_last(*last);
  return impl_->action(&v1::ClientService::Stub::RequeueJob, req);
}

Result<farm::JobInfo> FarmClient::remove(const std::string& job_id, bool outputs) {
  v1::DeleteJobRequest req;
  req.set_job_id(job_id);
  req.set_outputs(outputs);
  return impl_->action(&v1::ClientService::Stub::DeleteJob, req);
}

Result<std::string> FarmClient::drain_worker(const std::string& worker) {
  return impl_->worker_action(&v1::ClientService::Stub::DrainWorker, worker);
}

Result<std::string> FarmClient::disable_worker(const std::string& worker) {
  return impl_->worker_action(&v1::ClientService::Stub::DisableWorker, worker);
}

Result<std::string> FarmClient::enable_worker(const std::string& worker) {
  return impl_->worker_action(&v1::ClientService::Stub::EnableWorker, worker);
}

Result<std::vector<farm::BandLogLine>> FarmClient::logs(const std::string& job_id, int frame,
                                                        int band, int64_t after) {
  if (!impl_->broken.ok()) return impl_->broken;
  std::vector<farm::BandLogLine> out;
  for (;;) {
    v1::ListLogsRequest req;
    req.set_job_id(job_id);
    if (frame >= 0) req.set_frame(frame);
    if (band >= 0) req.set_band(band);
    req.set_after_seq(after);
    v1::ListLogsResponse resp;
    grpc::ClientContext ctx;
    impl_->prepare(ctx, rpc::kShortCall);
    if (Status s = impl_->check(impl_->stub->ListLogs(&ctx, req, &resp)); !s.ok()) return s;
    for (const v1::BandLogLine& l : resp.lines()) {
      out.push_back({l.seq(), l.frame(), l.band(), l.lease_id(), l.worker_id(), l.text()});
      after = l.seq();
    }
    if (resp.lines_size() < farm::kMaxEventsPerCall) return out;
  }
}

Result<std::vector<farm::HistoryEntry>> FarmClient::events(const std::string& job_id,
                                                           int64_t after) {
  if (!impl_->broken.ok()) return impl_->broken;
  std::vector<farm::HistoryEntry> out;
  // Pages of the server's cap until one comes back short.
  for (;;) {
    v1::ListEventsRequest req;
    req.set_job_id(job_id);
    req.set_after_seq(after);
    v1::ListEventsResponse resp;
    grpc::ClientContext ctx;
    impl_->prepare(ctx, rpc::kShortCall);
    if (Status s = impl_->check(impl_->stub->ListEvents(&ctx, req, &resp)); !s.ok()) return s;
    for (const v1::JobEvent& e : resp.events()) {
      out.push_back({e.seq(), e.unix_seconds(), e.frame(), e.band(), e.text()});
      after = e.seq();
    }
    if (resp.events_size() < farm::kMaxEventsPerCall) return out;
  }
}

Result<std::vector<farm::WorkerInfo>> FarmClient::workers() {
  if (!impl_->broken.ok()) return impl_->broken;
  v1::ListWorkersResponse resp;
  grpc::ClientContext ctx;
  impl_->prepare(ctx, rpc::kShortCall);
  if (Status s = impl_->check(impl_->stub->ListWorkers(&ctx, v1::ListWorkersRequest(), &resp));
      !s.ok()) {
    return s;
  }
  std::vector<farm::WorkerInfo> out;
  for (const v1::WorkerInfo& w : resp.workers()) out.push_back(rpc::FromProto(w));
  return out;
}

Result<farm::JobInfo> FarmClient::watch(
    const std::string& job_id, const std::function<void(const farm::JobInfo&)>& on_update) {
  if (!impl_->broken.ok()) return impl_->broken;
  constexpr int kStreamSeconds = 30;
  // A farm that goes away (a coordinator restarting) is waited for: the job
  // is in its store, and the watch goes on once it is back.
  auto give_up = std::chrono::steady_clock::now() + kRetryFor;
  farm::Millis backoff{250};
  bool reached = false;
  for (;;) {
    v1::WatchJobRequest req;
    req.set_job_id(job_id);
    req.set_max_seconds(kStreamSeconds);
    grpc::ClientContext ctx;
    impl_->prepare(ctx, farm::Millis(kStreamSeconds * 1000) + rpc::kShortCall);
    auto reader = impl_->stub->WatchJob(&ctx, req);
    v1::JobStatus status;
    std::optional<farm::JobInfo> last;
    while (reader->Read(&status)) {
      last = rpc::FromProto(status);
      on_update(*last);
    }
    if (Status s = impl_->check(reader->Finish()); !s.ok()) {
      // Only a farm that knew the job is waited for; an address that never
      // answered is an error at once.
      if (last) reached = true;
      if (!reached || !transient(s) || std::chrono::steady_clock::now() + backoff > give_up)
        return s;
      std::this_thread::sleep_for(backoff);
      backoff = std::min(backoff * 2, farm::Millis(1000));
      continue;
    }
    if (last && farm::is_terminal(last->state)) return *last;
    reached = true;
    give_up = std::chrono::steady_clock::now() + kRetryFor;
    backoff = farm::Millis(250);
  }
}

FetchedFiles::~FetchedFiles() {
  if (tmp_.empty()) return;
  out_.close();
  std::error_code ec;
  fs::remove(tmp_, ec);
}

bool FetchedFiles::failed(Status s) {
  status_ = std::move(s);
  return false;
}

bool FetchedFiles::take(const farm::FileChunk& chunk) {
  if (!status_.ok()) return false;
  if (chunk.offset == 0) {
    // The name comes from the coordinator: it must not lead elsewhere.
    if (Status s = farm::check_plain_file_name(chunk.file_name, peer_ + " sent a file"); !s.ok())
      return failed(s);
    path_ = dest_(chunk.frame, chunk.file_name);
    std::error_code ec;
    const fs::path path(path_);
    if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
    tmp_ = path_ + ".partial";
    out_ = std::ofstream(tmp_, std::ios::binary | std::ios::trunc);
    if (!out_) return failed(Status(Code::kFailedPrecondition, path_ + ": cannot write"));
    expected_ = 0;
  }
  if (chunk.offset != expected_ || !out_.is_open()) {
    return failed(Internal("frame " + std::to_string(chunk.frame) + " arrived out of order"));
  }
  out_.write(chunk.data.data(), static_cast<std::streamsize>(chunk.data.size()));
  expected_ += static_cast<int64_t>(chunk.data.size());
  if (chunk.last) {
    out_.close();
    if (!out_) return failed(Status(Code::kFailedPrecondition, path_ + ": cannot write"));
    std::error_code ec;
    fs::rename(tmp_, path_, ec);
    if (ec) return failed(Status(Code::kFailedPrecondition, path_ + ": " + ec.message()));
    tmp_.clear();
    written_.push_back(path_);
  }
  return true;
}

Result<std::vector<std::string>> FarmClient::fetch(const std::string& job_id,
                                                   const std::vector<int>& frames,
                                                   const FileDest& dest, bool cost_maps) {
  if (!impl_->broken.ok()) return impl_->broken;
  v1::FetchResultsRequest req;
  req.set_job_id(job_id);
  req.set_cost_maps(cost_maps);
  for (int f : frames) req.add_frames(f);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, rpc::kDataCall);
  auto reader = impl_->stub->FetchResults(&ctx, req);
  FetchedFiles files(dest, impl_->peer);
  v1::FileChunk received;
  while (reader->Read(&received)) {
    if (!files.take(rpc::FromProto(std::move(received)))) {
      ctx.TryCancel();
      reader->Finish();
      return files.status();
    }
  }
  if (Status s = impl_->check(reader->Finish()); !s.ok()) return s;
  return files.written();
}

}  // namespace locus::client
