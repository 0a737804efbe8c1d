// The one place where the farm's plain types meet gRPC and proto/locus.proto:
// locus::Status <-> grpc::Status, FromProto/ToProto for every farm message,
// and the channel and server settings every binary uses (message sizes,
// deadlines). The coordinator, the worker and the CLI all link it.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "common/base/status.h"
#include "common/farm/auth.h"
#include "common/farm/types.h"
#include "proto/locus.grpc.pb.h"

namespace locus::rpc {

// Every RPC has a deadline; these are the defaults by kind of call.
inline constexpr farm::Millis kShortCall{10000};  // status, cancel, heartbeat, register
inline constexpr farm::Millis kDataCall{120000};  // submit, scene, band results, fetch
inline constexpr farm::Millis kPollSlack{5000};   // a long poll's deadline beyond its wait

grpc::Status ToGrpc(const Status& status);
// `peer` names the other end in the message: "farm at 127.0.0.1:7000".
Status FromGrpc(const grpc::Status& status, const std::string& peer);

// A coordinator as a client or worker reaches it: a channel with the
// farm's explicit message size limits, and the token each call carries.
struct Connection {
  std::shared_ptr<grpc::Channel> channel;
  std::string token;
  std::string address;
};

// TLS when the credentials name a CA or a client certificate (verifying
// the coordinator against --tls-ca); plaintext to a loopback address, or
// anywhere with `insecure`. Otherwise FailedPrecondition saying what to
// give: a token must not cross a network in clear text by accident.
Result<Connection> connect(const std::string& address, const farm::Credentials& credentials);
// 127.0.0.0/8, ::1, localhost or a unix socket: traffic that never leaves
// the host.
bool is_loopback(const std::string& address);
// The deadline and the bearer token of one call. Every client and worker
// call goes through it.
void prepare(grpc::ClientContext& context, const Connection& connection, farm::Millis timeout);

// How a coordinator serves: TLS from PEM files (with a CA: mutual TLS,
// which worker calls then require), or plaintext only when `insecure`;
// tokens through `auth` (open: every call allowed, `insecure` only).
struct ServerSecurity {
  bool insecure = false;
  std::string tls_cert;
  std::string tls_key;
  std::string tls_ca;
  farm::Authenticator auth;
};
// What a coordinator must refuse to start with, in words naming the flags.
Status check_server_security(const ServerSecurity& security);
void configure_server(grpc::ServerBuilder& builder);

// ---- FromProto / ToProto ----
v1::RenderSettings ToProto(const farm::RenderSettings& s);
farm::RenderSettings FromProto(const v1::RenderSettings& p);
v1::RenderStats ToProto(const Stats& s);
Stats FromProto(const v1::RenderStats& p);
v1::JobState ToProto(farm::JobState s);
farm::JobState FromProto(v1::JobState s);
v1::JobStatus ToProto(const farm::JobInfo& j);
farm::JobInfo FromProto(const v1::JobStatus& p);
v1::WorkerInfo ToProto(const farm::WorkerInfo& w);
farm::WorkerInfo FromProto(const v1::WorkerInfo& p);
v1::BandLogLine ToProto(const farm::BandLogLine& l);
v1::Attempt ToProto(const farm::AttemptInfo& a);
v1::FrameStatus ToProto(const farm::FrameDetail& f);
v1::WorkerStatus ToProto(const farm::WorkerDetail& w);
v1::BandTask ToProto(const farm::BandLease& t);
farm::BandLease FromProto(const v1::BandTask& p);
farm::SubmitRequest FromProto(const v1::JobSpec& p);
v1::JobSpec ToProto(const farm::SubmitRequest& r);
// The pixels are moved out of `o`: they are the bulk of the farm's traffic.
v1::CompleteBandRequest ToProto(farm::BandOutput&& o);
farm::BandOutput FromProto(const v1::CompleteBandRequest& p);
v1::FileChunk ToProto(const farm::FileChunk& c);
// The bytes are moved out of `p` (a chunk is up to 1 MiB of a frame file).
farm::FileChunk FromProto(v1::FileChunk&& p);

}  // namespace locus::rpc
