#include "server/grpc_service.h"

#include <spdlog/spdlog.h>

#include <exception>

#include "server/rpc.h"

namespace locus::rpc {
namespace {

// Bounds every field a peer controls before it reaches the logic.
constexpr size_t kMaxIdBytes = 256;
constexpr int kMaxLeasesPerHeartbeat = 1024;

// Runs a handler body; whatever escapes (a bad_alloc from an absurd request)
// becomes an error for that call, never the end of the coordinator.
template <typename F>
grpc::Status guarded(const char* rpc, F&& body) {
  try {
    return ToGrpc(body());
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", rpc, e.what());
    return grpc::Status(grpc::StatusCode::INTERNAL, std::string(rpc) + ": " + e.what());
  }
}

Status check_id(const std::string& id, const char* what) {
  if (id.empty()) return InvalidArgument(std::string(what) + " is required");
  if (id.size() > kMaxIdBytes) return InvalidArgument(std::string(what) + " is too long");
  return Status::Ok();
}

}  // namespace

class CoordinatorServer::ClientImpl final : public v1::ClientService::Service {
 public:
  explicit ClientImpl(farm::Coordinator& c) : c_(c) {}

  grpc::Status SubmitJob(grpc::ServerContext*, const v1::SubmitJobRequest* req,
                         v1::SubmitJobResponse* resp) override {
    return guarded("SubmitJob", [&]() -> Status {
      farm::SubmitRequest submit = FromProto(req->spec());
      submit.request_id = req->request_id();
      auto r = c_.submit(submit);
      if (!r.ok()) return r.status();
      resp->set_job_id(r->job_id);
      *resp->mutable_status() = ToProto(*r);
      return Status::Ok();
    });
  }

  grpc::Status GetJob(grpc::ServerContext*, const v1::GetJobRequest* req,
                      v1::JobStatus* resp) override {
    return guarded("GetJob", [&]() -> Status {
      if (Status s = check_id(req->job_id(), "job_id"); !s.ok()) return s;
      auto r = c_.job(req->job_id());
      if (!r.ok()) return r.status();
      *resp = ToProto(*r);
      return Status::Ok();
    });
  }

  grpc::Status ListJobs(grpc::ServerContext*, const v1::ListJobsRequest*,
                        v1::ListJobsResponse* resp) override {
    return guarded("ListJobs", [&]() -> Status {
      for (const farm::JobInfo& j : c_.jobs()) *resp->add_jobs() = ToProto(j);
      return Status::Ok();
    });
  }

  grpc::Status WatchJob(grpc::ServerContext* ctx, const v1::WatchJobRequest* req,
                        grpc::ServerWriter<v1::JobStatus>* writer) override {
    return guarded("WatchJob", [&]() -> Status {
      if (Status s = check_id(req->job_id(), "job_id"); !s.ok()) return s;
      const farm::Millis max(
          req->max_seconds() > 0 ? static_cast<int64_t>(req->max_seconds()) * 1000 : 30000);
      return c_.watch(
          req->job_id(), max, [ctx] { return ctx->IsCancelled(); },
          [writer](const farm::JobInfo& j) { return writer->Write(ToProto(j)); });
    });
  }

  grpc::Status CancelJob(grpc::ServerContext*, const v1::CancelJobRequest* req,
                         v1::CancelJobResponse* resp) override {
    return guarded("CancelJob", [&]() -> Status {
      if (Status s = check_id(req->job_id(), "job_id"); !s.ok()) return s;
      auto r = c_.cancel(req->job_id());
      if (!r.ok()) return r.status();
      *resp->mutable_status() = ToProto(*r);
      return Status::Ok();
    });
  }

  grpc::Status ListWorkers(grpc::ServerContext*, const v1::ListWorkersRequest*,
                           v1::ListWorkersResponse* resp) override {
    return guarded("ListWorkers", [&]() -> Status {
      for (const farm::WorkerInfo& w : c_.workers()) *resp->add_workers() = ToProto(w);
      return Status::Ok();
    });
  }

  grpc::Status FetchResults(grpc::ServerContext*, const v1::FetchResultsRequest* req,
                            grpc::ServerWriter<v1::FileChunk>* writer) override {
    return guarded("FetchResults", [&]() -> Status {
      if (Status s = check_id(req->job_id(), "job_id"); !s.ok()) return s;
      std::vector<int> frames(req->frames().begin(), req->frames().end());
      return c_.fetch(req->job_id(), frames, [writer](const farm::FileChunk& c) {
        v1::FileChunk p;
        p.set_frame(c.frame);
        p.set_file_name(c.file_name);
        p.set_offset(c.offset);
        p.set_data(c.data);
        p.set_last(c.last);
        return writer->Write(p);
      });
    });
  }

 private:
  farm::Coordinator& c_;
};

class CoordinatorServer::WorkerImpl final : public v1::WorkerService::Service {
 public:
  explicit WorkerImpl(farm::Coordinator& c) : c_(c) {}

  grpc::Status Register(grpc::ServerContext* ctx, const v1::RegisterRequest* req,
                        v1::RegisterResponse* resp) override {
    return guarded("Register", [&]() -> Status {
      const std::string name = req->name().empty() ? ctx->peer() : req->name();
      farm::Registration r = c_.register_worker(name, req->threads());
      resp->set_worker_id(r.worker_id);
      resp->set_heartbeat_ms(static_cast<int32_t>(r.heartbeat.count()));
      resp->set_lease_ms(static_cast<int32_t>(r.lease.count()));
      return Status::Ok();
    });
  }

  grpc::Status GetTask(grpc::ServerContext* ctx, const v1::GetTaskRequest* req,
                       v1::GetTaskResponse* resp) override {
    return guarded("GetTask", [&]() -> Status {
      if (Status s = check_id(req->worker_id(), "worker_id"); !s.ok()) return s;
      auto r = c_.get_task(req->worker_id(), farm::Millis(std::max(0, req->wait_ms())),
                           [ctx] { return ctx->IsCancelled(); });
      if (!r.ok()) return r.status();
      if (r->has_value()) *resp->mutable_task() = ToProto(**r);
      return Status::Ok();
    });
  }

  grpc::Status GetScene(grpc::ServerContext*, const v1::GetSceneRequest* req,
                        v1::GetSceneResponse* resp) override {
    return guarded("GetScene", [&]() -> Status {
      if (Status s = check_id(req->worker_id(), "worker_id"); !s.ok()) return s;
      if (Status s = check_id(req->scene_hash(), "scene_hash"); !s.ok()) return s;
      auto r = c_.get_scene(req->worker_id(), req->scene_hash());
      if (!r.ok()) return r.status();
      *resp->mutable_scene() = **r;
      return Status::Ok();
    });
  }

  grpc::Status CompleteBand(grpc::ServerContext*, const v1::CompleteBandRequest* req,
                            v1::CompleteBandResponse* resp) override {
    return guarded("CompleteBand", [&]() -> Status {
      if (Status s = check_id(req->worker_id(), "worker_id"); !s.ok()) return s;
      if (Status s = check_id(req->lease_id(), "lease_id"); !s.ok()) return s;
      auto r = c_.complete_band(FromProto(*req));
      if (!r.ok()) return r.status();
      resp->set_accepted(r->accepted);
      resp->set_reason(r->reason);
      return Status::Ok();
    });
  }

  grpc::Status Heartbeat(grpc::ServerContext*, const v1::HeartbeatRequest* req,
                         v1::HeartbeatResponse* resp) override {
    return guarded("Heartbeat", [&]() -> Status {
      if (Status s = check_id(req->worker_id(), "worker_id"); !s.ok()) return s;
      if (req->lease_ids_size() > kMaxLeasesPerHeartbeat)
        return InvalidArgument("too many lease ids");
      std::vector<std::string> leases(req->lease_ids().begin(), req->lease_ids().end());
      auto r = c_.heartbeat(req->worker_id(), leases);
      if (!r.ok()) return r.status();
      for (const std::string& id : *r) resp->add_revoked_lease_ids(id);
      return Status::Ok();
    });
  }

 private:
  farm::Coordinator& c_;
};

CoordinatorServer::CoordinatorServer(farm::Coordinator& coordinator)
    : coordinator_(coordinator),
      client_(std::make_unique<ClientImpl>(coordinator)),
      worker_(std::make_unique<WorkerImpl>(coordinator)) {}

CoordinatorServer::~CoordinatorServer() { shutdown(farm::Millis(0)); }

Result<int> CoordinatorServer::start(const std::string& address) {
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(address, grpc::InsecureServerCredentials(), &port);
  configure_server(builder);
  builder.RegisterService(client_.get());
  builder.RegisterService(worker_.get());
  server_ = builder.BuildAndStart();
  if (!server_ || port == 0) {
    server_.reset();
    return Status(Code::kUnavailable,
                  "cannot listen on " + address + " (address in use, or not local?)");
  }
  return port;
}

void CoordinatorServer::shutdown(farm::Millis grace) {
  if (!server_) return;
  // Long polls and watches return once the coordinator stops.
  coordinator_.shutdown();
  server_->Shutdown(std::chrono::system_clock::now() + grace);
  server_->Wait();
  server_.reset();
}

void CoordinatorServer::wait() {
  if (server_) server_->Wait();
}

}  // namespace locus::rpc
