// The coordinator fuzzer's body (fuzz_coordinator.cpp), also replayed on
// the corpus by the gtest suite (tests/fuzz_corpus_test.cpp). Each input is
// a sequence of protobuf requests (coordinator_input.h), parsed as the
// gRPC server would and passed to the same handlers (server/handlers.h) in
// front of a fresh Coordinator. Whatever a client or worker sends must come
// back as an answer or an error, never a crash; and the coordinator must
// still answer afterwards.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "server/coordinator.h"
#include "server/handlers.h"
#include "tests/fuzz/coordinator_input.h"
#include "tests/fuzz/fuzz_util.h"

namespace locus::fuzz {
namespace coordinator_target {

// What earlier answers gave, for kFillIds.
struct Ids {
  std::string worker, lease, job, scene;
  int band_floats = 0;
};

inline void fill(google::protobuf::Message&, const Ids&) {}  // nothing to fill
inline void fill(v1::GetJobRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::WatchJobRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::CancelJobRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::FetchResultsRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::JobActionRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::SetPriorityRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::RequeueJobRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::ListEventsRequest& r, const Ids& ids) { r.set_job_id(ids.job); }
inline void fill(v1::WorkerActionRequest& r, const Ids& ids) { r.set_worker(ids.worker); }
inline void fill(v1::GetTaskRequest& r, const Ids& ids) { r.set_worker_id(ids.worker); }
inline void fill(v1::GetSceneRequest& r, const Ids& ids) {
  r.set_worker_id(ids.worker);
  r.set_scene_hash(ids.scene);
}
inline void fill(v1::CompleteBandRequest& r, const Ids& ids) {
  r.set_worker_id(ids.worker);
  r.set_lease_id(ids.lease);
}
inline void fill(v1::HeartbeatRequest& r, const Ids& ids) {
  r.set_worker_id(ids.worker);
  r.add_lease_ids(ids.lease);
}

template <typename Req>
inline bool parse(const std::string& bytes, uint8_t kind, const Ids& ids, Req* req) {
  if (!req->ParseFromString(bytes)) return false;
  if (kind & kFillIds) fill(*req, ids);
  return true;
}

inline void run(rpc::Handlers& h, uint8_t kind, const std::string& bytes, Ids& ids) {
  const farm::Caller anyone = farm::Caller::anyone();
  switch ((kind & 0x0f) % kRpcCount) {
    case kSubmitJob: {
      v1::SubmitJobRequest req;
      v1::SubmitJobResponse resp;
      if (parse(bytes, kind, ids, &req) && h.SubmitJob(req, anyone, &resp).ok())
        ids.job = resp.job_id();
      break;
    }
    case kGetJob: {
      v1::GetJobRequest req;
      v1::JobStatus resp;
      if (parse(bytes, kind, ids, &req)) h.GetJob(req, anyone, &resp);
      break;
    }
    case kListJobs: {
      v1::ListJobsRequest req;
      v1::ListJobsResponse resp;
      if (parse(bytes, kind, ids, &req)) h.ListJobs(req, anyone, &resp);
      break;
    }
    case kWatchJob: {
      // One status, then the "client" goes away: a watch never blocks here.
      v1::WatchJobRequest req;
      if (parse(bytes, kind, ids, &req))
        h.WatchJob(
            req, anyone, [] { return true; }, [](const v1::JobStatus&) { return false; });
      break;
    }
    case kCancelJob: {
      v1::CancelJobRequest req;
      v1::CancelJobResponse resp;
      if (parse(bytes, kind, ids, &req)) h.CancelJob(req, anyone, &resp);
      break;
    }
    case kListWorkers: {
      v1::ListWorkersRequest req;
      v1::ListWorkersResponse resp;
      if (parse(bytes, kind, ids, &req)) h.ListWorkers(req, &resp);
      break;
    }
    case kFetchResults: {
      v1::FetchResultsRequest req;
      if (parse(bytes, kind, ids, &req))
        h.FetchResults(req, anyone, [](const v1::FileChunk&) { return true; });
      break;
    }
    case kRegister: {
      v1::RegisterRequest req;
      v1::RegisterResponse resp;
      if (parse(bytes, kind, ids, &req) && h.Register(req, "fuzz", &resp).ok())
        ids.worker = resp.worker_id();
      break;
    }
    case kGetTask: {
      v1::GetTaskRequest req;
      v1::GetTaskResponse resp;
      if (!parse(bytes, kind, ids, &req)) break;
      req.set_wait_ms(0);  // a long poll would only wait
      if (h.GetTask(
               req, [] { return false; }, &resp)
              .ok() &&
          resp.has_task()) {
        const v1::BandTask& t = resp.task();
        ids.lease = t.lease_id();
        ids.scene = t.scene_hash();
        ids.band_floats = t.width() * (t.y1() - t.y0()) * 3;
      }
      break;
    }
    case kGetScene: {
      v1::GetSceneRequest req;
      v1::GetSceneResponse resp;
      if (parse(bytes, kind, ids, &req)) h.GetScene(req, &resp);
      break;
    }
    case kCompleteBand: {
      v1::CompleteBandRequest req;
      v1::CompleteBandResponse resp;
      if (!parse(bytes, kind, ids, &req)) break;
      if ((kind & kRightSize) && ids.band_floats > 0)
        req.mutable_rgb()->Resize(ids.band_floats, 0.5f);
      h.CompleteBand(req, &resp);
      break;
    }
    case kHeartbeat: {
      v1::HeartbeatRequest req;
      v1::HeartbeatResponse resp;
      if (parse(bytes, kind, ids, &req)) h.Heartbeat(req, &resp);
      break;
    }
    case kPauseJob: {
      v1::JobActionRequest req;
      v1::JobActionResponse resp;
      if (!parse(bytes, kind, ids, &req)) break;
      if (bytes.size() % 2 == 1) {
        h.RetryJob(req, anyone, &resp);
      } else if (kind & kRightSize) {
        h.ResumeJob(req, anyone, &resp);
      } else {
        h.PauseJob(req, anyone, &resp);
      }
      break;
    }
    case kSetPriority: {
      v1::JobActionResponse resp;
      if (kind & kRightSize) {
        v1::RequeueJobRequest req;
        if (parse(bytes, kind, ids, &req)) h.RequeueJob(req, anyone, &resp);
        break;
      }
      v1::SetPriorityRequest req;
      if (parse(bytes, kind, ids, &req)) h.SetPriority(req, anyone, &resp);
      break;
    }
    case kListEvents: {
      v1::ListEventsRequest req;
      v1::ListEventsResponse resp;
      if (parse(bytes, kind, ids, &req)) h.ListEvents(req, anyone, &resp);
      break;
    }
    case kWorkerAction: {
      v1::WorkerActionRequest req;
      v1::WorkerActionResponse resp;
      if (!parse(bytes, kind, ids, &req)) break;
      switch (bytes.size() % 3) {
        case 0:
          h.DrainWorker(req, anyone, &resp);
          break;
        case 1:
          h.DisableWorker(req, anyone, &resp);
          break;
        default:
          h.EnableWorker(req, anyone, &resp);
      }
      break;
    }
  }
}

}  // namespace coordinator_target

// One input: a sequence of requests against a fresh Coordinator.
inline int fuzz_coordinator(const uint8_t* data, size_t size) {
  using namespace coordinator_target;
  quiet_logs();
  farm::CoordinatorOptions o;
  o.group_commit = farm::Millis(0);  // each accepted band synced at once: no waiting per input
  o.data_dir = scratch_dir() + "/coordinator";
  // Small limits keep each input fast; the checks are the same code.
  o.limits.max_resolution = 256;
  o.limits.max_frames = 64;
  o.limits.max_bands = 4096;
  o.limits.max_jobs = 8;
  o.limits.max_objects = 2000;
  farm::Coordinator coordinator(o);
  if (!coordinator.start().ok()) violated("the coordinator did not start");
  rpc::Handlers handlers(coordinator);
  Ids ids;
  size_t at = 0;
  for (int requests = 0; at + 3 <= size && requests < 64; ++requests) {
    const uint8_t kind = data[at];
    const size_t n = std::min<size_t>(data[at + 1] | (data[at + 2] << 8), size - at - 3);
    const std::string bytes(reinterpret_cast<const char*>(data) + at + 3, n);
    at += 3 + n;
    run(handlers, kind, bytes, ids);
  }
  // Still serving.
  v1::ListJobsResponse jobs;
  if (!handlers.ListJobs(v1::ListJobsRequest(), farm::Caller::anyone(), &jobs).ok())
    violated("ListJobs failed");
  coordinator.shutdown();
  return 0;
}

}  // namespace locus::fuzz
