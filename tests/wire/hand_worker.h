// A worker driven by hand through the raw WorkerService (tests/wire/), for
// tests that shape its calls themselves.
#pragma once

#include "tests/farm_fixture.h"

namespace locus::farm::testing_farm {

// A worker driven by hand through the raw WorkerService: it leases, fetches
// the scene and renders with the worker's own BandRenderer, and sends what
// the test makes of the result.
class HandWorker {
 public:
  HandWorker(std::unique_ptr<v1::WorkerService::Stub> stub,
             std::function<void(grpc::ClientContext&)> prepare)
      : stub_(std::move(stub)), prepare_(std::move(prepare)), renderer_(1) {
    grpc::ClientContext ctx;
    prepare_(ctx);
    v1::RegisterResponse who;
    EXPECT_TRUE(stub_->Register(&ctx, v1::RegisterRequest(), &who).ok());
    id_ = who.worker_id();
  }

  // GetScene's answer for the scene of content hash `hash`.
  v1::GetSceneResponse scene(const std::string& hash) {
    grpc::ClientContext ctx;
    prepare_(ctx);
    v1::GetSceneRequest req;
    req.set_worker_id(id_);
    req.set_scene_hash(hash);
    v1::GetSceneResponse resp;
    EXPECT_TRUE(stub_->GetScene(&ctx, req, &resp).ok());
    return resp;
  }

  std::optional<v1::BandTask> lease() {
    std::vector<v1::BandTask> one = leases(1);
    if (one.empty()) return std::nullopt;
    return one.front();
  }

  // Up to `max_bands` bands in one GetTask (GetTaskRequest.max_bands).
  std::vector<v1::BandTask> leases(int max_bands) {
    grpc::ClientContext ctx;
    prepare_(ctx);
    v1::GetTaskRequest get;
    get.set_worker_id(id_);
    get.set_wait_ms(2000);
    get.set_max_bands(max_bands);
    v1::GetTaskResponse leased;
    EXPECT_TRUE(stub_->GetTask(&ctx, get, &leased).ok());
    return tasks(leased);
  }

  // The bands of a GetTask answer: its task and its `more`.
  static std::vector<v1::BandTask> tasks(const v1::GetTaskResponse& r) {
    std::vector<v1::BandTask> out;
    if (r.has_task()) out.push_back(r.task());
    out.insert(out.end(), r.more().begin(), r.more().end());
    return out;
  }

  // The band rendered as a worker of this release would, or of an older one
  // (which knows no encodings and sends floats) when `as_older`.
  v1::CompleteBandRequest render(const v1::BandTask& task, bool as_older) {
    BandLease lease = rpc::FromProto(task);
    if (!renderer_.has_scene(lease.scene_hash)) {
      const v1::GetSceneResponse resp = scene(lease.scene_hash);
      EXPECT_TRUE(renderer_.add_scene_bytes(lease.scene_hash, resp.scene(), "scene").ok());
    }
    if (as_older) lease.encoding = BandEncoding::kFloat32;
    auto out = renderer_.render(lease);
    EXPECT_TRUE(out.ok()) << out.status().message();
    out->worker_id = id_;
    out->lease_id = lease.lease_id;
    return rpc::ToProto(std::move(*out));
  }

  grpc::Status send(const v1::CompleteBandRequest& req, v1::CompleteBandResponse* resp) {
    grpc::ClientContext ctx;
    prepare_(ctx);
    return stub_->CompleteBand(&ctx, req, resp);
  }

  const std::string& id() const { return id_; }

 private:
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  std::function<void(grpc::ClientContext&)> prepare_;
  BandRenderer renderer_;
  std::string id_;
};

// A farm whose bands the test leases and returns itself.
class HandWorkerTest : public FarmTest {
 protected:
  HandWorker hand_worker() {
    return HandWorker(worker_stub(worker_creds_),
                      [this](grpc::ClientContext& ctx) { prepare(ctx); });
  }
  // The farm started, a hand worker registered, the job submitted; its id
  // ("" with a test failure if it was refused).
  std::string start_with_job(const SubmitRequest& r) {
    start();
    auto job = client_->submit(r);
    EXPECT_TRUE(job.ok()) << job.status().message();
    return job.ok() ? job->job_id : "";
  }
  // The job once it ended, which must be a success whose frames are a
  // single-process render's (nullopt with a test failure otherwise).
  std::optional<JobInfo> succeeded(const std::string& job_id, const SubmitRequest& r) {
    auto done = client_->watch(job_id, [](const JobInfo&) {});
    EXPECT_TRUE(done.ok()) << done.status().message();
    if (!done.ok()) return std::nullopt;
    EXPECT_EQ(done->state, JobState::kSucceeded) << done->error;
    expect_identical(*done, r);
    return *done;
  }
};

}  // namespace locus::farm::testing_farm
