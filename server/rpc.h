// The one place where the farm's plain types meet gRPC and proto/locus.proto:
// locus::Status <-> grpc::Status, FromProto/ToProto for every farm message,
// and the channel and server settings every binary uses (message sizes,
// deadlines). The coordinator, the worker and the CLI all link it.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <string>

#include "common/status.h"
#include "proto/locus.grpc.pb.h"
#include "server/coordinator.h"
#include "server/farm_types.h"

namespace locus::rpc {

// Every RPC has a deadline; these are the defaults by kind of call.
inline constexpr farm::Millis kShortCall{10000};  // status, cancel, heartbeat, register
inline constexpr farm::Millis kDataCall{120000};  // submit, scene, band results, fetch
inline constexpr farm::Millis kPollSlack{5000};   // a long poll's deadline beyond its wait

grpc::Status ToGrpc(const Status& status);
// `peer` names the other end in the message: "farm at 127.0.0.1:7000".
Status FromGrpc(const grpc::Status& status, const std::string& peer);

// Insecure channel with the farm's explicit message size limits. Issue #7
// adds TLS and tokens here.
std::shared_ptr<grpc::Channel> make_channel(const std::string& address);
void configure_server(grpc::ServerBuilder& builder);
void set_deadline(grpc::ClientContext& context, farm::Millis timeout);

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
v1::BandTask ToProto(const farm::BandTask& t);
farm::BandTask FromProto(const v1::BandTask& p);
farm::SubmitRequest FromProto(const v1::JobSpec& p);
v1::JobSpec ToProto(const farm::SubmitRequest& r);
// The pixels are moved out of `o`: they are the bulk of the farm's traffic.
v1::CompleteBandRequest ToProto(farm::BandOutput&& o);
farm::BandOutput FromProto(const v1::CompleteBandRequest& p);

}  // namespace locus::rpc
