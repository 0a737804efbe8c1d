#include "server/grpc_service.h"

#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <exception>
#include <fstream>
#include <mutex>
#include <sstream>

#include "server/handler_pool.h"
#include "server/metrics.h"

namespace locus::rpc {
namespace {

// The first value of a call's `authorization` header, "" when absent.
std::string_view authorization(const grpc::ServerContextBase& ctx) {
  const auto& md = ctx.client_metadata();
  auto it = md.find("authorization");
  return it == md.end() ? std::string_view()
                        : std::string_view(it->second.data(), it->second.size());
}

// TLS verified a client certificate against --tls-ca.
bool peer_certificate_verified(const grpc::ServerContextBase& ctx) {
  const auto auth = ctx.auth_context();
  return auth && auth->IsPeerAuthenticated() &&
         !auth->FindPropertyValues(GRPC_X509_PEM_CERT_PROPERTY_NAME).empty();
}

// Logs a refused call with the peer and the reason (never the token): at
// most kRefusalsLogged a second, so that a flood of bad calls cannot flood
// the log; the rest are counted in the next line that is written.
void log_refusal(const std::string& peer, const Status& why) {
  constexpr int kRefusalsLogged = 20;
  static std::mutex mu;
  static auto window = std::chrono::steady_clock::now();
  static int logged = 0, suppressed = 0;
  std::lock_guard lk(mu);
  const auto now = std::chrono::steady_clock::now();
  if (now - window >= std::chrono::seconds(1)) {
    window = now;
    logged = 0;
  }
  if (logged >= kRefusalsLogged) {
    ++suppressed;
    return;
  }
  ++logged;
  // The message starts with the call: "refused WorkerService.Register: ...".
  if (suppressed > 0) {
    spdlog::warn("refused {} (peer {}; {} refusals before this one not logged)", why.message(),
                 peer, suppressed);
    suppressed = 0;
    return;
  }
  spdlog::warn("refused {} (peer {})", why.message(), peer);
}

// The caller's credentials, checked; a refusal is logged and counted.
Result<farm::Caller> admit(const farm::Authenticator& auth, farm::CoordinatorMetrics& metrics,
                           const grpc::ServerContextBase& ctx, farm::Role role, const char* rpc,
                           const google::protobuf::Message& request) {
  Result<farm::Caller> caller =
      auth.identify(role, authorization(ctx), peer_certificate_verified(ctx), rpc);
  if (!caller.ok()) {
    metrics.add_bytes(rpc, request.ByteSizeLong(), 0);
    log_refusal(ctx.peer(), caller.status());
  }
  return caller;
}

// An admitted call's answer from its handler, `body`: whatever escapes it
// (a bad_alloc from an absurd request) becomes an error for that call,
// never the end of the coordinator. The request's bytes and the response's
// (`response` null for a stream, whose writes count their own) go to the
// metrics.
template <typename F>
grpc::Status answer(farm::CoordinatorMetrics& metrics, const grpc::ServerContextBase& ctx,
                    const farm::Caller& caller, const char* rpc,
                    const google::protobuf::Message& request,
                    const google::protobuf::Message* response, F&& body) {
  grpc::Status status;
  try {
    if constexpr (std::is_invocable_v<F, const farm::Caller&>) {
      const Status s = body(caller);
      // The wrong user's action: logged like a refused token (never the token).
      if (s.code() == Code::kPermissionDenied) log_refusal(ctx.peer(), s);
      status = ToGrpc(s);
    } else {
      status = ToGrpc(body());
    }
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", rpc, e.what());
    status = grpc::Status(grpc::StatusCode::INTERNAL, std::string(rpc) + ": " + e.what());
  }
  metrics.add_bytes(rpc, request.ByteSizeLong(),
                    status.ok() && response ? response->ByteSizeLong() : 0);
  return status;
}

// Every call: credentials first (admit), then the handler (answer).
template <typename F>
grpc::Status serve(const farm::Authenticator& auth, farm::CoordinatorMetrics& metrics,
                   const grpc::ServerContextBase& ctx, farm::Role role, const char* rpc,
                   const google::protobuf::Message& request,
                   const google::protobuf::Message* response, F&& body) {
  const Result<farm::Caller> caller = admit(auth, metrics, ctx, role, rpc, request);
  if (!caller.ok()) return ToGrpc(caller.status());
  return answer(metrics, ctx, *caller, rpc, request, response, std::forward<F>(body));
}

// A stream's writes, counted.
template <typename Message>
auto counted_writer(farm::CoordinatorMetrics& metrics, const char* rpc,
                    grpc::ServerWriter<Message>* writer) {
  return [&metrics, rpc, writer](const Message& m) {
    metrics.add_bytes(rpc, 0, m.ByteSizeLong());
    return writer->Write(m);
  };
}

// A call answered later, on another thread: `start(done)` begins it and
// `done(status)` finishes it (the response filled), exactly once. What
// escapes `start` becomes an error for the call if it was not answered.
// Returns what `start` returns (a default value after an exception).
template <typename Start>
auto answer_later(grpc::ServerUnaryReactor* reactor, farm::CoordinatorMetrics& metrics,
                  const char* rpc, const google::protobuf::Message* request,
                  const google::protobuf::Message* response, Start&& start) {
  auto answered = std::make_shared<std::atomic<bool>>(false);
  std::function<void(Status)> done = [reactor, &metrics, rpc, request, response,
                                      answered](Status s) {
    answered->store(true);
    metrics.add_bytes(rpc, request->ByteSizeLong(), s.ok() ? response->ByteSizeLong() : 0);
    reactor->Finish(ToGrpc(s));
  };
  using R = decltype(start(std::move(done)));
  try {
    return start(std::move(done));
  } catch (const std::exception& e) {
    spdlog::error("{}: {}", rpc, e.what());
    if (!answered->load()) {
      reactor->Finish(grpc::Status(grpc::StatusCode::INTERNAL, std::string(rpc) + ": " + e.what()));
    }
    if constexpr (!std::is_void_v<R>) return R{};
  }
}

constexpr farm::Role kClient = farm::Role::kClient;
constexpr farm::Role kWorker = farm::Role::kWorker;

}  // namespace

class CoordinatorServer::ClientImpl final : public v1::ClientService::Service {
 public:
  ClientImpl(Handlers& h, const farm::Authenticator& auth, farm::CoordinatorMetrics& m)
      : h_(h), auth_(auth), m_(m) {}

  grpc::Status SubmitJob(grpc::ServerContext* ctx, const v1::SubmitJobRequest* req,
                         v1::SubmitJobResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.SubmitJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.SubmitJob(*req, c, resp); });
  }

  grpc::Status GetJob(grpc::ServerContext* ctx, const v1::GetJobRequest* req,
                      v1::JobStatus* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.GetJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.GetJob(*req, c, resp); });
  }

  grpc::Status ListJobs(grpc::ServerContext* ctx, const v1::ListJobsRequest* req,
                        v1::ListJobsResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.ListJobs", *req, resp,
                 [&](const farm::Caller& c) { return h_.ListJobs(*req, c, resp); });
  }

  grpc::Status WatchJob(grpc::ServerContext* ctx, const v1::WatchJobRequest* req,
                        grpc::ServerWriter<v1::JobStatus>* writer) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.WatchJob", *req, nullptr,
                 [&](const farm::Caller& c) {
                   return h_.WatchJob(
                       *req, c, [ctx] { return ctx->IsCancelled(); },
                       counted_writer(m_, "ClientService.WatchJob", writer));
                 });
  }

  grpc::Status CancelJob(grpc::ServerContext* ctx, const v1::CancelJobRequest* req,
                         v1::CancelJobResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.CancelJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.CancelJob(*req, c, resp); });
  }

  grpc::Status SetPriority(grpc::ServerContext* ctx, const v1::SetPriorityRequest* req,
                           v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.SetPriority", *req, resp,
                 [&](const farm::Caller& c) { return h_.SetPriority(*req, c, resp); });
  }

  grpc::Status PauseJob(grpc::ServerContext* ctx, const v1::JobActionRequest* req,
                        v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.PauseJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.PauseJob(*req, c, resp); });
  }

  grpc::Status ResumeJob(grpc::ServerContext* ctx, const v1::JobActionRequest* req,
                         v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.ResumeJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.ResumeJob(*req, c, resp); });
  }

  grpc::Status GetFarm(grpc::ServerContext* ctx, const v1::GetFarmRequest* req,
                       v1::FarmSnapshot* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.GetFarm", *req, resp,
                 [&](const farm::Caller& c) { return h_.GetFarm(*req, c, resp); });
  }

  grpc::Status GetFrame(grpc::ServerContext* ctx, const v1::GetFrameRequest* req,
                        v1::FrameStatus* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.GetFrame", *req, resp,
                 [&](const farm::Caller& c) { return h_.GetFrame(*req, c, resp); });
  }

  grpc::Status GetWorker(grpc::ServerContext* ctx, const v1::GetWorkerRequest* req,
                         v1::WorkerStatus* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.GetWorker", *req, resp,
                 [&](const farm::Caller& c) { return h_.GetWorker(*req, c, resp); });
  }

  grpc::Status RetryJob(grpc::ServerContext* ctx, const v1::JobActionRequest* req,
                        v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.RetryJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.RetryJob(*req, c, resp); });
  }

  grpc::Status RequeueJob(grpc::ServerContext* ctx, const v1::RequeueJobRequest* req,
                          v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.RequeueJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.RequeueJob(*req, c, resp); });
  }

  grpc::Status DeleteJob(grpc::ServerContext* ctx, const v1::DeleteJobRequest* req,
                         v1::JobActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.DeleteJob", *req, resp,
                 [&](const farm::Caller& c) { return h_.DeleteJob(*req, c, resp); });
  }

  grpc::Status ListLogs(grpc::ServerContext* ctx, const v1::ListLogsRequest* req,
                        v1::ListLogsResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.ListLogs", *req, resp,
                 [&](const farm::Caller& c) { return h_.ListLogs(*req, c, resp); });
  }

  grpc::Status ListEvents(grpc::ServerContext* ctx, const v1::ListEventsRequest* req,
                          v1::ListEventsResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.ListEvents", *req, resp,
                 [&](const farm::Caller& c) { return h_.ListEvents(*req, c, resp); });
  }

  grpc::Status DrainWorker(grpc::ServerContext* ctx, const v1::WorkerActionRequest* req,
                           v1::WorkerActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.DrainWorker", *req, resp,
                 [&](const farm::Caller& c) { return h_.DrainWorker(*req, c, resp); });
  }

  grpc::Status DisableWorker(grpc::ServerContext* ctx, const v1::WorkerActionRequest* req,
                             v1::WorkerActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.DisableWorker", *req, resp,
                 [&](const farm::Caller& c) { return h_.DisableWorker(*req, c, resp); });
  }

  grpc::Status EnableWorker(grpc::ServerContext* ctx, const v1::WorkerActionRequest* req,
                            v1::WorkerActionResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.EnableWorker", *req, resp,
                 [&](const farm::Caller& c) { return h_.EnableWorker(*req, c, resp); });
  }

  grpc::Status ListWorkers(grpc::ServerContext* ctx, const v1::ListWorkersRequest* req,
                           v1::ListWorkersResponse* resp) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.ListWorkers", *req, resp,
                 [&] { return h_.ListWorkers(*req, resp); });
  }

  grpc::Status FetchResults(grpc::ServerContext* ctx, const v1::FetchResultsRequest* req,
                            grpc::ServerWriter<v1::FileChunk>* writer) override {
    return serve(auth_, m_, *ctx, kClient, "ClientService.FetchResults", *req, nullptr,
                 [&](const farm::Caller& c) {
                   return h_.FetchResults(*req, c,
                                          counted_writer(m_, "ClientService.FetchResults", writer));
                 });
  }

 private:
  Handlers& h_;
  const farm::Authenticator& auth_;
  farm::CoordinatorMetrics& m_;
};

// GetTask on the callback API: the long poll parks in the coordinator
// (Coordinator::poll_band) and holds no thread; it is answered when a band
// comes, its time runs out, the coordinator stops or the worker goes
// (OnCancel). Deleted when gRPC is done with it and start() has returned,
// whichever is last.
class PollReactor final : public grpc::ServerUnaryReactor {
 public:
  explicit PollReactor(farm::Coordinator& c) : c_(c) {}
  // The poll started (its ticket; 0: answered already).
  void started(uint64_t ticket) {
    bool cancelled;
    {
      std::lock_guard lk(mu_);
      ticket_ = ticket;
      cancelled = cancelled_;
    }
    if (cancelled && ticket != 0) c_.cancel_poll(ticket);
    release();
  }
  void OnCancel() override {
    uint64_t ticket;
    {
      std::lock_guard lk(mu_);
      cancelled_ = true;
      ticket = ticket_;
    }
    if (ticket != 0) c_.cancel_poll(ticket);
  }
  void OnDone() override { release(); }

 private:
  void release() {
    if (refs_.fetch_sub(1) == 1) delete this;
  }
  farm::Coordinator& c_;
  std::mutex mu_;
  uint64_t ticket_ = 0;
  bool cancelled_ = false;
  std::atomic<int> refs_{2};
};

// The worker service on gRPC's callback API, so that a thousand connected
// workers cost memory, not threads (the synchronous server holds a thread
// per call in progress). gRPC's thread checks the credentials and hands
// the call to the handler pool (handler_pool.h), which answers it, or
// starts it to be answered later (GetTask, CompleteBand): gRPC's few
// threads never wait for the coordinator's lock.
class CoordinatorServer::WorkerImpl final : public v1::WorkerService::CallbackService {
 public:
  WorkerImpl(Handlers& h, farm::Coordinator& c, const farm::Authenticator& auth,
             farm::CoordinatorMetrics& m)
      : h_(h), c_(c), auth_(auth), m_(m), pool_(c.options().handler_threads) {}

  grpc::ServerUnaryReactor* Register(grpc::CallbackServerContext* ctx,
                                     const v1::RegisterRequest* req,
                                     v1::RegisterResponse* resp) override {
    return on_pool(ctx, kUrgent, [this, ctx, req, resp] {
      return serve(auth_, m_, *ctx, kWorker, "WorkerService.Register", *req, resp,
                   [&] { return h_.Register(*req, ctx->peer(), resp); });
    });
  }

  grpc::ServerUnaryReactor* GetTask(grpc::CallbackServerContext* ctx, const v1::GetTaskRequest* req,
                                    v1::GetTaskResponse* resp) override {
    static constexpr const char* kRpc = "WorkerService.GetTask";
    if (auto caller = arrived(*ctx, kRpc, *req, req->worker_id()); !caller.ok())
      return now(ctx, ToGrpc(caller.status()));
    auto* reactor = new PollReactor(c_);
    pool_.post([this, reactor, req, resp] {
      const uint64_t ticket =
          answer_later(reactor, m_, kRpc, req, resp, [&](std::function<void(Status)> done) {
            return h_.StartGetTask(*req, resp, std::move(done));
          });
      reactor->started(ticket);
    });
    return reactor;
  }

  grpc::ServerUnaryReactor* GetScene(grpc::CallbackServerContext* ctx,
                                     const v1::GetSceneRequest* req,
                                     v1::GetSceneResponse* resp) override {
    static constexpr const char* kRpc = "WorkerService.GetScene";
    auto caller = arrived(*ctx, kRpc, *req, req->worker_id());
    if (!caller.ok()) return now(ctx, ToGrpc(caller.status()));
    return on_pool(ctx, kUrgent, [this, ctx, req, resp, caller = *caller] {
      return answer(m_, *ctx, caller, kRpc, *req, resp, [&] { return h_.GetScene(*req, resp); });
    });
  }

  grpc::ServerUnaryReactor* CompleteBand(grpc::CallbackServerContext* ctx,
                                         const v1::CompleteBandRequest* req,
                                         v1::CompleteBandResponse* resp) override {
    // Answered once the band is durable (the coordinator's group commit),
    // from the commit thread: no thread waits for the disk.
    static constexpr const char* kRpc = "WorkerService.CompleteBand";
    if (auto caller = arrived(*ctx, kRpc, *req, req->worker_id()); !caller.ok())
      return now(ctx, ToGrpc(caller.status()));
    grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
    pool_.post([this, reactor, req, resp] {
      answer_later(reactor, m_, kRpc, req, resp, [&](std::function<void(Status)> done) {
        h_.StartCompleteBand(*req, resp, std::move(done));
      });
    });
    return reactor;
  }

  grpc::ServerUnaryReactor* Heartbeat(grpc::CallbackServerContext* ctx,
                                      const v1::HeartbeatRequest* req,
                                      v1::HeartbeatResponse* resp) override {
    static constexpr const char* kRpc = "WorkerService.Heartbeat";
    auto caller = arrived(*ctx, kRpc, *req, req->worker_id());
    if (!caller.ok()) return now(ctx, ToGrpc(caller.status()));
    return on_pool(ctx, kUrgent, [this, ctx, req, resp, caller = *caller] {
      return answer(m_, *ctx, caller, kRpc, *req, resp, [&] { return h_.Heartbeat(*req, resp); });
    });
  }

 private:
  static constexpr bool kUrgent = true;
  // A call answered on the spot.
  static grpc::ServerUnaryReactor* now(grpc::CallbackServerContext* ctx,
                                       const grpc::Status& status) {
    grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
    reactor->Finish(status);
    return reactor;
  }
  // A worker's call, its credentials checked (a refusal is logged and
  // counted): its worker counts as seen now (Coordinator::worker_call_arrived),
  // whenever a handler gets to it.
  Result<farm::Caller> arrived(const grpc::CallbackServerContext& ctx, const char* rpc,
                               const google::protobuf::Message& req, const std::string& worker_id) {
    Result<farm::Caller> caller = admit(auth_, m_, ctx, kWorker, rpc, req);
    if (caller.ok()) c_.worker_call_arrived(worker_id);
    return caller;
  }
  // A call answered by `body` (credentials and all) on the handler pool.
  template <typename F>
  grpc::ServerUnaryReactor* on_pool(grpc::CallbackServerContext* ctx, bool urgent, F body) {
    grpc::ServerUnaryReactor* reactor = ctx->DefaultReactor();
    pool_.post([reactor, body = std::move(body)] { reactor->Finish(body()); }, urgent);
    return reactor;
  }
  Handlers& h_;
  farm::Coordinator& c_;
  const farm::Authenticator& auth_;
  farm::CoordinatorMetrics& m_;
  // Last: joined first, after the server has stopped (CoordinatorServer::shutdown).
  HandlerPool pool_;
};

CoordinatorServer::CoordinatorServer(farm::Coordinator& coordinator)
    : coordinator_(coordinator),
      handlers_(coordinator),
      client_(std::make_unique<ClientImpl>(handlers_, auth_, coordinator.metrics())),
      worker_(std::make_unique<WorkerImpl>(handlers_, coordinator, auth_, coordinator.metrics())) {}

CoordinatorServer::~CoordinatorServer() { shutdown(farm::Millis(0)); }

Result<int> CoordinatorServer::start(const std::string& address, ServerSecurity security) {
  if (Status s = check_server_security(security); !s.ok()) return s;
  std::shared_ptr<grpc::ServerCredentials> creds;
  if (!security.tls_cert.empty()) {
    auto read = [](const std::string& path, const char* flag) -> Result<std::string> {
      std::ifstream in(path, std::ios::binary);
      if (!in) return FailedPrecondition(std::string(flag) + " " + path + ": cannot read the file");
      std::ostringstream text;
      text << in.rdbuf();
      return text.str();
    };
    grpc::SslServerCredentialsOptions ssl(security.tls_ca.empty()
                                              ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                              // Clients may present one; worker calls require one
                                              // (Authenticator::require_worker_certificate).
                                              : GRPC_SSL_REQUEST_CLIENT_CERTIFICATE_AND_VERIFY);
    grpc::SslServerCredentialsOptions::PemKeyCertPair pair;
    auto cert = read(security.tls_cert, "--tls-cert");
    if (!cert.ok()) return cert.status();
    auto key = read(security.tls_key, "--tls-key");
    if (!key.ok()) return key.status();
    pair.cert_chain = *cert;
    pair.private_key = *key;
    ssl.pem_key_cert_pairs.push_back(pair);
    if (!security.tls_ca.empty()) {
      auto ca = read(security.tls_ca, "--tls-ca");
      if (!ca.ok()) return ca.status();
      ssl.pem_root_certs = *ca;
    }
    creds = grpc::SslServerCredentials(ssl);
    security.auth.require_worker_certificate(!security.tls_ca.empty());
  } else {
    creds = grpc::InsecureServerCredentials();
  }
  auth_ = std::move(security.auth);
  tls_cert_ = security.tls_cert;
  tls_key_ = security.tls_key;

  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(address, creds, &port);
  configure_server(builder);
  builder.RegisterService(client_.get());
  builder.RegisterService(worker_.get());
  builder.RegisterService(&health_service_);
  server_ = builder.BuildAndStart();
  if (!server_ || port == 0) {
    server_.reset();
    return Status(Code::kUnavailable,
                  "cannot listen on " + address + " (address in use, or not local?" +
                      (security.tls_cert.empty() ? "" : " Or --tls-cert/--tls-key do not match.") +
                      ")");
  }
  health_service_.set_ready(true);
  health_.set_ready(true);
  return port;
}

Result<int> CoordinatorServer::serve_http(HttpServerOptions options, HttpOptions api) {
  if (!server_) return FailedPrecondition("serve_http() before start()");
  options.tls_cert = tls_cert_;  // the same certificate as the gRPC port
  options.tls_key = tls_key_;
  http_api_ = std::make_unique<HttpApi>(coordinator_, handlers_, auth_, api);
  auto http = HttpServer::start(options, *http_api_);
  if (!http.ok()) {
    http_api_.reset();
    return http.status();
  }
  http_ = std::move(*http);
  return http_->port();
}

Result<int> CoordinatorServer::serve_health(const std::string& address) {
  auto port = health_.start(address);
  if (port.ok()) health_.set_ready(server_ != nullptr);
  return port;
}

void CoordinatorServer::drain(farm::Millis max, farm::Millis grace) {
  if (!server_) return;
  // Load balancers and probes first, so that nothing new is sent here.
  health_service_.set_ready(false);
  health_.set_ready(false);
  coordinator_.drain();
  coordinator_.wait_drained(max);
  shutdown(grace);
}

void CoordinatorServer::shutdown(farm::Millis grace) {
  if (!server_) return;
  http_.reset();  // its requests finish first; they use the coordinator
  health_service_.shutdown();
  health_.set_ready(false);
  // Long polls and watches return now; calls in flight (a band's result)
  // get until `grace`, and the store is still open for them.
  coordinator_.stop_waiting();
  server_->Shutdown(std::chrono::system_clock::now() + grace);
  server_->Wait();
  server_.reset();
  coordinator_.shutdown();
  health_.shutdown();
}

void CoordinatorServer::wait() {
  if (server_) server_->Wait();
}

}  // namespace locus::rpc
