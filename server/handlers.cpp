#include "server/handlers.h"

#include <algorithm>
#include <memory>
#include <mutex>

#include "common/base/log.h"
#include "proto/wire/rpc.h"
#include "server/await.h"

namespace locus::rpc {
namespace {

// Bounds on what a peer sends, before anything reaches the logic.
constexpr size_t kMaxIdBytes = 256;
constexpr size_t kMaxNameBytes = 200;
constexpr size_t kMaxOutputBytes = 1024;
constexpr int kMaxLeasesPerHeartbeat = 1024;
constexpr int kMaxFetchFrames = farm::kMaxFramesPerJob;
// Bands in one GetTask answer or one CompleteBand call (max_bands, more).
constexpr int kMaxBandsPerCall = 64;

int bands_per_call(int asked) { return std::clamp(asked, 1, kMaxBandsPerCall); }

Status check_id(const std::string& id, const char* what) {
  if (id.empty()) return InvalidArgument(std::string(what) + " is required");
  if (id.size() > kMaxIdBytes) return InvalidArgument(std::string(what) + " is too long");
  return Status::Ok();
}

// Names and workers' log lines go into logs and tables: bounded, one line,
// printable.
std::string printable(const std::string& text, size_t max_bytes = kMaxNameBytes) {
  std::string out = text.substr(0, max_bytes);
  for (char& c : out)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  return out;
}

}  // namespace

Status Handlers::SubmitJob(const v1::SubmitJobRequest& req, const farm::Caller& caller,
                           v1::SubmitJobResponse* resp) {
  if (req.spec().output().size() > kMaxOutputBytes)
    return InvalidArgument("output: longer than " + std::to_string(kMaxOutputBytes) + " bytes");
  // Bounded before the copy: the checks name the limits.
  if (req.spec().require_size() > static_cast<int>(farm::kMaxTags) ||
      req.spec().after_size() > static_cast<int>(farm::kMaxAfter)) {
    return InvalidArgument("require: at most " + std::to_string(farm::kMaxTags) +
                           " tags; after: at most " + std::to_string(farm::kMaxAfter) + " jobs");
  }
  farm::SubmitRequest r = FromProto(req.spec());
  r.scene_name = printable(r.scene_name);
  r.request_id = req.request_id();
  auto job = c_.submit(r, caller.user);
  if (!job.ok()) return job.status();
  resp->set_job_id(job->job_id);
  *resp->mutable_status() = ToProto(*job);
  return Status::Ok();
}

Status Handlers::GetJob(const v1::GetJobRequest& req, const farm::Caller& caller,
                        v1::JobStatus* resp) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  auto r = c_.job(req.job_id(), caller);
  if (!r.ok()) return r.status();
  *resp = ToProto(*r);
  return Status::Ok();
}

Status Handlers::ListJobs(const v1::ListJobsRequest&, const farm::Caller& caller,
                          v1::ListJobsResponse* resp) {
  for (const farm::JobInfo& j : c_.jobs(caller)) *resp->add_jobs() = ToProto(j);
  return Status::Ok();
}

Status Handlers::WatchJob(const v1::WatchJobRequest& req, const farm::Caller& caller,
                          const farm::CancelledFn& cancelled,
                          const std::function<bool(const v1::JobStatus&)>& write) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  const farm::Millis max(req.max_seconds() > 0 ? static_cast<int64_t>(req.max_seconds()) * 1000
                                               : 30000);
  return c_.watch(req.job_id(), caller, max, cancelled,
                  [&write](const farm::JobInfo& j) { return write(ToProto(j)); });
}

Status Handlers::CancelJob(const v1::CancelJobRequest& req, const farm::Caller& caller,
                           v1::CancelJobResponse* resp) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  auto r = c_.cancel(req.job_id(), caller);
  if (!r.ok()) return r.status();
  *resp->mutable_status() = ToProto(*r);
  return Status::Ok();
}

namespace {
Status job_action(const std::string& job_id, v1::JobActionResponse* resp,
                  const std::function<Result<farm::JobInfo>()>& call) {
  if (Status s = check_id(job_id, "job_id"); !s.ok()) return s;
  auto r = call();
  if (!r.ok()) return r.status();
  *resp->mutable_status() = ToProto(*r);
  return Status::Ok();
}
}  // namespace

Status Handlers::SetPriority(const v1::SetPriorityRequest& req, const farm::Caller& caller,
                             v1::JobActionResponse* resp) {
  return job_action(req.job_id(), resp, [&] {
    return c_.set_priority(req.job_id(), req.priority(), req.preempt(), caller);
  });
}

Status Handlers::PauseJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                          v1::JobActionResponse* resp) {
  return job_action(req.job_id(), resp, [&] { return c_.pause(req.job_id(), caller); });
}

Status Handlers::ResumeJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                           v1::JobActionResponse* resp) {
  return job_action(req.job_id(), resp, [&] { return c_.resume(req.job_id(), caller); });
}

Status Handlers::RetryJob(const v1::JobActionRequest& req, const farm::Caller& caller,
                          v1::JobActionResponse* resp) {
  return job_action(req.job_id(), resp, [&] { return c_.retry(req.job_id(), caller); });
}

Status Handlers::RequeueJob(const v1::RequeueJobRequest& req, const farm::Caller& caller,
                            v1::JobActionResponse* resp) {
  const auto bound = [](bool has, int32_t v) { return has ? std::optional<int>(v) : std::nullopt; };
  return job_action(req.job_id(), resp, [&] {
    return c_.requeue(req.job_id(), bound(req.has_frame_first(), req.frame_first()),
                      bound(req.has_frame_last(), req.frame_last()), caller);
  });
}

Status Handlers::DeleteJob(const v1::DeleteJobRequest& req, const farm::Caller& caller,
                           v1::JobActionResponse* resp) {
  return job_action(req.job_id(), resp,
                    [&] { return c_.delete_job(req.job_id(), req.outputs(), caller); });
}

Status Handlers::ListLogs(const v1::ListLogsRequest& req, const farm::Caller& caller,
                          v1::ListLogsResponse* resp) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  const int limit =
      req.limit() > 0 ? std::min(req.limit(), farm::kMaxEventsPerCall) : farm::kMaxEventsPerCall;
  auto r =
      c_.logs(req.job_id(), req.has_frame() ? req.frame() : -1, req.has_band() ? req.band() : -1,
              std::max<int64_t>(0, req.after_seq()), limit, caller);
  if (!r.ok()) return r.status();
  for (const farm::BandLogLine& l : *r) *resp->add_lines() = ToProto(l);
  return Status::Ok();
}

Status Handlers::ListEvents(const v1::ListEventsRequest& req, const farm::Caller& caller,
                            v1::ListEventsResponse* resp) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  const int limit =
      req.limit() > 0 ? std::min(req.limit(), farm::kMaxEventsPerCall) : farm::kMaxEventsPerCall;
  auto r = c_.events(req.job_id(), std::max<int64_t>(0, req.after_seq()), limit, caller);
  if (!r.ok()) return r.status();
  for (const farm::HistoryEntry& e : *r) {
    v1::JobEvent* p = resp->add_events();
    p->set_seq(e.seq);
    p->set_unix_seconds(e.at);
    p->set_frame(e.frame);
    p->set_band(e.band);
    p->set_text(e.text);
  }
  return Status::Ok();
}

namespace {
Status worker_action(const v1::WorkerActionRequest& req, v1::WorkerActionResponse* resp,
                     const char* state, const std::function<Result<std::string>()>& call) {
  if (Status s = check_id(req.worker(), "worker"); !s.ok()) return s;
  auto r = call();
  if (!r.ok()) return r.status();
  resp->set_worker_name(*r);
  resp->set_state(state);
  return Status::Ok();
}
}  // namespace

Status Handlers::DrainWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                             v1::WorkerActionResponse* resp) {
  return worker_action(req, resp, "draining",
                       [&] { return c_.drain_worker(req.worker(), caller); });
}

Status Handlers::DisableWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                               v1::WorkerActionResponse* resp) {
  return worker_action(req, resp, "disabled",
                       [&] { return c_.set_worker_disabled(req.worker(), true, caller); });
}

Status Handlers::EnableWorker(const v1::WorkerActionRequest& req, const farm::Caller& caller,
                              v1::WorkerActionResponse* resp) {
  return worker_action(req, resp, "enabled",
                       [&] { return c_.set_worker_disabled(req.worker(), false, caller); });
}

Status Handlers::ListWorkers(const v1::ListWorkersRequest&, v1::ListWorkersResponse* resp) {
  for (const farm::WorkerInfo& w : c_.workers()) *resp->add_workers() = ToProto(w);
  return Status::Ok();
}

Status Handlers::GetFarm(const v1::GetFarmRequest& req, const farm::Caller& caller,
                         v1::FarmSnapshot* resp) {
  const farm::Coordinator::Snapshot s = c_.snapshot(req.since(), caller);
  resp->set_version(s.version);
  resp->set_unchanged(s.unchanged);
  for (const farm::JobInfo& j : s.jobs) *resp->add_jobs() = ToProto(j);
  for (const farm::WorkerInfo& w : s.workers) *resp->add_workers() = ToProto(w);
  return Status::Ok();
}

Status Handlers::GetFrame(const v1::GetFrameRequest& req, const farm::Caller& caller,
                          v1::FrameStatus* resp) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  auto r = c_.frame_detail(req.job_id(), req.frame(), caller);
  if (!r.ok()) return r.status();
  *resp = ToProto(*r);
  return Status::Ok();
}

Status Handlers::GetWorker(const v1::GetWorkerRequest& req, const farm::Caller& caller,
                           v1::WorkerStatus* resp) {
  if (Status s = check_id(req.worker(), "worker"); !s.ok()) return s;
  auto r = c_.worker_detail(req.worker(), caller);
  if (!r.ok()) return r.status();
  *resp = ToProto(*r);
  return Status::Ok();
}

Status Handlers::FetchResults(const v1::FetchResultsRequest& req, const farm::Caller& caller,
                              const std::function<bool(const v1::FileChunk&)>& write) {
  if (Status s = check_id(req.job_id(), "job_id"); !s.ok()) return s;
  if (req.frames_size() > kMaxFetchFrames)
    return InvalidArgument("frames: at most " + std::to_string(kMaxFetchFrames) + " per fetch");
  std::vector<int> frames(req.frames().begin(), req.frames().end());
  return c_.fetch(
      req.job_id(), caller, frames,
      [&write](const farm::FileChunk& c) { return write(ToProto(c)); }, req.cost_maps());
}

Status Handlers::Register(const v1::RegisterRequest& req, const std::string& peer,
                          v1::RegisterResponse* resp) {
  const std::string name = printable(req.name().empty() ? peer : req.name());
  if (req.tags_size() > static_cast<int>(farm::kMaxTags))
    return InvalidArgument("tags: at most " + std::to_string(farm::kMaxTags));
  const std::vector<std::string> tags(req.tags().begin(), req.tags().end());
  // Encodings this coordinator does not know are ignored (a newer worker).
  const auto offered = [&](v1::BandEncoding e) {
    return std::find(req.encodings().begin(), req.encodings().end(), e) != req.encodings().end();
  };
  const farm::EncodingOffers offers{offered(v1::BAND_PNG8_DEFLATE), offered(v1::BAND_EXR_ZIP)};
  auto r = c_.register_worker(name, std::clamp(req.threads(), 1, 1024), tags, offers);
  if (!r.ok()) return r.status();
  resp->set_worker_id(r->worker_id);
  resp->set_heartbeat_ms(static_cast<int32_t>(r->heartbeat.count()));
  resp->set_lease_ms(static_cast<int32_t>(r->lease.count()));
  return Status::Ok();
}

Status Handlers::answer_poll(const std::string& worker_id, farm::Coordinator::PollAnswer answer,
                             int max_bands, v1::GetTaskResponse* resp) {
  if (!answer.ok()) return answer.status();
  if (answer->has_value()) {
    *resp->mutable_task() = ToProto(**answer);
    for (const farm::BandLease& l : c_.lease_more(worker_id, bands_per_call(max_bands) - 1))
      *resp->add_more() = ToProto(l);
  }
  resp->set_drain(c_.worker_draining(worker_id));
  return Status::Ok();
}

uint64_t Handlers::StartGetTask(const v1::GetTaskRequest& req, v1::GetTaskResponse* resp,
                                std::function<void(Status)> done) {
  if (Status s = check_id(req.worker_id(), "worker_id"); !s.ok()) {
    done(s);
    return 0;
  }
  return c_.poll_band(req.worker_id(), farm::Millis(std::max(0, req.wait_ms())),
                      [this, worker_id = req.worker_id(), max_bands = req.max_bands(), resp,
                       done = std::move(done)](farm::Coordinator::PollAnswer answer) {
                        done(answer_poll(worker_id, std::move(answer), max_bands, resp));
                      });
}

Status Handlers::GetTask(const v1::GetTaskRequest& req, const farm::CancelledFn& cancelled,
                         v1::GetTaskResponse* resp) {
  if (Status s = check_id(req.worker_id(), "worker_id"); !s.ok()) return s;
  return answer_poll(
      req.worker_id(),
      c_.lease_band(req.worker_id(), farm::Millis(std::max(0, req.wait_ms())), cancelled),
      req.max_bands(), resp);
}

Status Handlers::GetScene(const v1::GetSceneRequest& req, v1::GetSceneResponse* resp) {
  if (Status s = check_id(req.worker_id(), "worker_id"); !s.ok()) return s;
  if (Status s = check_id(req.scene_hash(), "scene_hash"); !s.ok()) return s;
  auto r = c_.get_scene(req.worker_id(), req.scene_hash());
  if (!r.ok()) return r.status();
  resp->set_scene(**r);
  return Status::Ok();
}

namespace {

// One result of a CompleteBand call (the request itself or one of its
// `more`), checked and bounded before it reaches the coordinator.
// `worker_id`: the call's (a further result's own may be left empty).
Result<farm::BandOutput> band_output(const v1::CompleteBandRequest& req,
                                     const std::string& worker_id) {
  Status checked = check_id(worker_id, "worker_id");
  if (checked.ok()) checked = check_id(req.lease_id(), "lease_id");
  if (checked.ok() && req.log_lines_size() > static_cast<int>(kMaxBandLogLines) + 1)
    checked = InvalidArgument("log_lines: at most " + std::to_string(kMaxBandLogLines));
  if (!checked.ok()) return checked;
  farm::BandOutput output = FromProto(req);
  output.worker_id = worker_id;
  output.error = output.error.substr(0, 4096);
  for (std::string& l : output.log_lines) l = printable(l, kMaxBandLogLineBytes);
  return output;
}

}  // namespace

void Handlers::StartCompleteBand(const v1::CompleteBandRequest& req, v1::CompleteBandResponse* resp,
                                 std::function<void(Status)> done) {
  // Every result is checked before any is stored: a bad one refuses the
  // call and stores none of them.
  std::vector<farm::BandOutput> outputs;
  Status checked = req.more_size() < kMaxBandsPerCall
                       ? Status::Ok()
                       : InvalidArgument("more: at most " + std::to_string(kMaxBandsPerCall - 1) +
                                         " further results in one call");
  auto one = [&req](int i) -> Result<farm::BandOutput> {
    if (i < 0) return band_output(req, req.worker_id());
    const v1::CompleteBandRequest& m = req.more(i);
    const std::string where = "more[" + std::to_string(i) + "]: ";
    if (m.more_size() > 0 || m.want_next() || m.max_next() > 0)
      return InvalidArgument(where + "a further result carries no more, want_next or max_next");
    if (!m.worker_id().empty() && m.worker_id() != req.worker_id())
      return InvalidArgument(where + "worker_id differs from the call's");
    Result<farm::BandOutput> r = band_output(m, req.worker_id());
    if (!r.ok()) return InvalidArgument(where + r.status().message());
    return r;
  };
  for (int i = -1; checked.ok() && i < req.more_size(); ++i) {
    Result<farm::BandOutput> r = one(i);
    if (r.ok()) {
      outputs.push_back(std::move(*r));
    } else {
      checked = r.status();
    }
  }
  if (!checked.ok()) {
    done(checked);
    return;
  }
  for (int i = 0; i < req.more_size(); ++i) resp->add_more();
  // A hand-back is the worker leaving: no next band for it.
  const bool want_next = req.want_next() && !req.handed_back();
  // The answer goes once every result has its outcome (an accepted one
  // once it is durable); the first failure, if any, is the call's.
  struct Pending {
    std::mutex mu;
    size_t left = 0;
    Status failed = Status::Ok();
    std::function<void(Status)> done;
  };
  auto pending = std::make_shared<Pending>();
  pending->left = outputs.size();
  pending->done = std::move(done);
  auto finish = [this, resp, pending, want_next, worker_id = req.worker_id(),
                 max_next = req.max_next()](size_t index, Result<farm::CompleteOutcome> r) {
    std::unique_lock lk(pending->mu);
    if (!r.ok()) {
      if (pending->failed.ok()) pending->failed = r.status();
    } else {
      v1::CompleteBandResponse* one =
          index == 0 ? resp : resp->mutable_more(static_cast<int>(index - 1));
      one->set_accepted(r->accepted);
      one->set_reason(r->reason);
    }
    if (--pending->left > 0) return;
    const Status failed = pending->failed;
    lk.unlock();
    if (failed.ok() && want_next) {
      // Leased only now that the results are durable (or refused), as the
      // worker's next GetTask would be. A wait of 0 answers at once, here;
      // a failure (a worker no longer known, a closing coordinator) leaves
      // `next` out and the worker's GetTask hears it.
      c_.poll_band(worker_id, farm::Millis(0), [&](farm::Coordinator::PollAnswer a) {
        v1::GetTaskResponse next;
        if (answer_poll(worker_id, std::move(a), max_next, &next).ok())
          *resp->mutable_next() = std::move(next);
      });
    }
    pending->done(failed);
  };
  std::vector<farm::Coordinator::CompleteDone> dones;
  for (size_t i = 0; i < outputs.size(); ++i) {
    dones.push_back([finish, i](Result<farm::CompleteOutcome> r) { finish(i, std::move(r)); });
  }
  c_.complete_bands_async(std::move(outputs), std::move(dones));
}

Status Handlers::CompleteBand(const v1::CompleteBandRequest& req, v1::CompleteBandResponse* resp) {
  return await_answer<Status>(
      [&](std::function<void(Status)> done) { StartCompleteBand(req, resp, std::move(done)); });
}

Status Handlers::Heartbeat(const v1::HeartbeatRequest& req, v1::HeartbeatResponse* resp) {
  if (Status s = check_id(req.worker_id(), "worker_id"); !s.ok()) return s;
  if (req.lease_ids_size() > kMaxLeasesPerHeartbeat) return InvalidArgument("too many lease ids");
  std::vector<std::string> leases(req.lease_ids().begin(), req.lease_ids().end());
  auto r = c_.heartbeat(req.worker_id(), leases);
  if (!r.ok()) return r.status();
  for (const std::string& id : *r) resp->add_revoked_lease_ids(id);
  resp->set_drain(c_.worker_draining(req.worker_id()));
  return Status::Ok();
}

}  // namespace locus::rpc
