// Each RPC's work on its request message: bounds on every field a peer
// controls, FromProto, the Coordinator call, ToProto. No grpc::ServerContext
// and no network: server/grpc_service.cpp wraps each handler in
// authentication and exception guarding, and the fuzzer
// (tests/fuzz/fuzz_coordinator.cpp) and tests call them directly.
#pragma once

#include <functional>
#include <string>

#include "common/farm/auth.h"
#include "proto/locus.pb.h"
#include "server/coordinator.h"

namespace locus::rpc {

class Handlers {
 public:
  explicit Handlers(farm::Coordinator& coordinator) : c_(coordinator) {}

  // ---- ClientService ----
  Status SubmitJob(const v1::SubmitJobRequest& req, const farm::Caller& caller,
                   v1::SubmitJobResponse* resp);
  // Reading: every client's, or with --private-jobs the owner's and admins'.
  Status GetJob(const v1::GetJobRequest& req, const farm::Caller& caller, v1::JobStatus* resp);
  Status ListJobs(const v1::ListJobsRequest& req, const farm::Caller& caller,
                  v1::ListJobsResponse* resp);
  // `write` returns false when the client has gone.
  Status WatchJob(const v1::WatchJobRequest& req, const farm::Caller& caller,
                  const farm::CancelledFn& cancelled,
                  const std::function<bool(const v1::JobStatus&)>& write);
  Status CancelJob(const v1::CancelJobRequest& req, const farm::Caller& caller,
                   v1::CancelJobResponse* resp);
  // The actions on a job: its owner's or an admin's (PERMISSION_DENIED).
  Status SetPriority(const v1::SetPriorityRequest& req, const farm::Caller& caller,
                     v1::JobActionResponse* resp);
  Status PauseJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                  v1::JobActionResponse* resp);
  Status ResumeJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                   v1::JobActionResponse* resp);
  Status RetryJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                  v1::JobActionResponse* resp);
  Status RequeueJob(const v1::RequeueJobRequest& req, const farm::Caller& caller,
                    v1::JobActionResponse* resp);
  Status DeleteJob(const v1::DeleteJobRequest& req, const farm::Caller& caller,
                   v1::JobActionResponse* resp);
  Status ListEvents(const v1::ListEventsRequest& req, const farm::Caller& caller,
                    v1::ListEventsResponse* resp);
  Status ListLogs(const v1::ListLogsRequest& req, const farm::Caller& caller,
                  v1::ListLogsResponse* resp);
  Status ListWorkers(const v1::ListWorkersRequest& req, v1::ListWorkersResponse* resp);
  // The dashboard's reads (also over gRPC): the farm with a cursor, one
  // frame's bands, one worker's recent work.
  Status GetFarm(const v1::GetFarmRequest& req, const farm::Caller& caller,
                 v1::FarmSnapshot* resp);
  Status GetFrame(const v1::GetFrameRequest& req, const farm::Caller& caller,
                  v1::FrameStatus* resp);
  Status GetWorker(const v1::GetWorkerRequest& req, const farm::Caller& caller,
                   v1::WorkerStatus* resp);
  // Admins only.
  Status DrainWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                     v1::WorkerActionResponse* resp);
  Status DisableWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                       v1::WorkerActionResponse* resp);
  Status EnableWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                      v1::WorkerActionResponse* resp);
  Status FetchResults(const v1::FetchResultsRequest& req, const farm::Caller& caller,
                      const std::function<bool(const v1::FileChunk&)>& write);

  // ---- WorkerService ----
  // `peer` names an unnamed worker.
  Status Register(const v1::RegisterRequest& req, const std::string& peer,
                  v1::RegisterResponse* resp);
  // Leases a band (Coordinator::poll_band); the RPC keeps its wire name.
  // `done` gets the status once `resp` is filled, exactly once, perhaps
  // before this returns. Returns the poll's ticket for
  // Coordinator::cancel_poll (0: answered already).
  uint64_t StartGetTask(const v1::GetTaskRequest& req, v1::GetTaskResponse* resp,
                        std::function<void(Status)> done);
  // The same, waiting here (tests, the fuzzer).
  Status GetTask(const v1::GetTaskRequest& req, const farm::CancelledFn& cancelled,
                 v1::GetTaskResponse* resp);
  Status GetScene(const v1::GetSceneRequest& req, v1::GetSceneResponse* resp);
  // A band's result (Coordinator::complete_band_async): `done` gets the
  // status once `resp` is filled, exactly once, perhaps before this
  // returns; for an accepted band once it is durable.
  void StartCompleteBand(const v1::CompleteBandRequest& req, v1::CompleteBandResponse* resp,
                         std::function<void(Status)> done);
  // The same, waiting here (tests, the fuzzer).
  Status CompleteBand(const v1::CompleteBandRequest& req, v1::CompleteBandResponse* resp);
  Status Heartbeat(const v1::HeartbeatRequest& req, v1::HeartbeatResponse* resp);

 private:
  // GetTask's response from the poll's answer.
  // GetTask's response from the poll's answer, with up to max_bands - 1
  // further bands (GetTaskRequest.max_bands) when it holds one.
  Status answer_poll(const std::string& worker_id, farm::Coordinator::PollAnswer answer,
                     int max_bands, v1::GetTaskResponse* resp);
  farm::Coordinator& c_;
};

}  // namespace locus::rpc
