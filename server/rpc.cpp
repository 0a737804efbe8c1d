#include "server/rpc.h"

namespace locus::rpc {

grpc::Status ToGrpc(const Status& s) {
  using G = grpc::StatusCode;
  G code = G::UNKNOWN;
  switch (s.code()) {
    case Code::kOk:
      return grpc::Status::OK;
    case Code::kInvalidArgument:
      code = G::INVALID_ARGUMENT;
      break;
    case Code::kNotFound:
      code = G::NOT_FOUND;
      break;
    case Code::kAlreadyExists:
      code = G::ALREADY_EXISTS;
      break;
    case Code::kFailedPrecondition:
      code = G::FAILED_PRECONDITION;
      break;
    case Code::kResourceExhausted:
      code = G::RESOURCE_EXHAUSTED;
      break;
    case Code::kPermissionDenied:
      code = G::PERMISSION_DENIED;
      break;
    case Code::kUnauthenticated:
      code = G::UNAUTHENTICATED;
      break;
    case Code::kUnavailable:
      code = G::UNAVAILABLE;
      break;
    case Code::kDeadlineExceeded:
      code = G::DEADLINE_EXCEEDED;
      break;
    case Code::kCancelled:
      code = G::CANCELLED;
      break;
    case Code::kAborted:
      code = G::ABORTED;
      break;
    case Code::kInternal:
      code = G::INTERNAL;
      break;
  }
  return grpc::Status(code, s.message());
}

Status FromGrpc(const grpc::Status& s, const std::string& peer) {
  using G = grpc::StatusCode;
  switch (s.error_code()) {
    case G::OK:
      return Status::Ok();
    case G::INVALID_ARGUMENT:
      return Status(Code::kInvalidArgument, s.error_message());
    case G::NOT_FOUND:
      return Status(Code::kNotFound, s.error_message());
    case G::ALREADY_EXISTS:
      return Status(Code::kAlreadyExists, s.error_message());
    case G::FAILED_PRECONDITION:
      return Status(Code::kFailedPrecondition, s.error_message());
    case G::RESOURCE_EXHAUSTED:
      return Status(Code::kResourceExhausted, peer + ": " + s.error_message());
    case G::PERMISSION_DENIED:
      return Status(Code::kPermissionDenied, peer + ": permission denied: " + s.error_message());
    case G::UNAUTHENTICATED:
      return Status(Code::kUnauthenticated, peer + ": not authenticated: " + s.error_message());
    case G::UNAVAILABLE:
      return Status(Code::kUnavailable, "cannot reach the " + peer + " (" + s.error_message() +
                                            "); is it running, and is the address right?");
    case G::DEADLINE_EXCEEDED:
      return Status(Code::kDeadlineExceeded, "the " + peer + " did not answer in time");
    case G::CANCELLED:
      return Status(Code::kCancelled, "call to the " + peer + " cancelled: " + s.error_message());
    case G::ABORTED:
      return Status(Code::kAborted, s.error_message());
    default:
      return Status(Code::kInternal, peer + ": " + s.error_message());
  }
}

std::shared_ptr<grpc::Channel> make_channel(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(farm::kMaxMessageBytes);
  args.SetMaxSendMessageSize(farm::kMaxMessageBytes);
  // Reconnect quickly after a coordinator restart rather than backing off
  // for minutes.
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

void configure_server(grpc::ServerBuilder& builder) {
  // A second server on a port in use must fail, not share it (gRPC sets
  // SO_REUSEPORT by default): two coordinators would split the workers.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.SetMaxReceiveMessageSize(farm::kMaxMessageBytes);
  builder.SetMaxSendMessageSize(farm::kMaxMessageBytes);
  // Long polls and watches each hold a thread of the synchronous server;
  // bound them so a flood of clients cannot exhaust the process.
  grpc::ResourceQuota quota("locus-coordinator");
  quota.SetMaxThreads(512);
  builder.SetResourceQuota(quota);
}

void set_deadline(grpc::ClientContext& context, farm::Millis timeout) {
  context.set_deadline(std::chrono::system_clock::now() + timeout);
}

// ---------------------------------------------------------------- conversions

v1::RenderSettings ToProto(const farm::RenderSettings& s) {
  v1::RenderSettings p;
  p.set_method(s.method);
  p.set_boxes(s.boxes);
  p.set_spp(s.spp);
  p.set_aa(s.aa);
  return p;
}

farm::RenderSettings FromProto(const v1::RenderSettings& p) {
  farm::RenderSettings s;
  s.method = p.method().empty() ? farm::RenderSettings{}.method : p.method();
  s.boxes = p.boxes().empty() ? farm::RenderSettings{}.boxes : p.boxes();
  s.spp = p.spp() == 0 ? 1 : p.spp();
  s.aa = p.has_aa() ? p.aa() : farm::RenderSettings{}.aa;
  return s;
}

v1::RenderStats ToProto(const Stats& s) {
  v1::RenderStats p;
  p.set_seconds_prepare(s.seconds_prepare);
  p.set_seconds_render(s.seconds_render);
  p.set_rays_eye(s.rays_eye);
  p.set_rays_reflected(s.rays_reflected);
  p.set_rays_refracted(s.rays_refracted);
  p.set_rays_shadow(s.rays_shadow);
  p.set_tests_ray_object(s.tests_ray_object);
  p.set_tests_shadow_volume(s.tests_shadow_volume);
  p.set_pixels_total(s.pixels_total);
  p.set_pixels_ray_traced(s.pixels_ray_traced);
  p.set_spans_total(s.spans_total);
  p.set_spans_ray_traced(s.spans_ray_traced);
  p.set_shadow_method(s.shadow_method);
  return p;
}

Stats FromProto(const v1::RenderStats& p) {
  Stats s;
  s.seconds_prepare = p.seconds_prepare();
  s.seconds_render = p.seconds_render();
  s.rays_eye = p.rays_eye();
  s.rays_reflected = p.rays_reflected();
  s.rays_refracted = p.rays_refracted();
  s.rays_shadow = p.rays_shadow();
  s.tests_ray_object = p.tests_ray_object();
  s.tests_shadow_volume = p.tests_shadow_volume();
  s.pixels_total = p.pixels_total();
  s.pixels_ray_traced = p.pixels_ray_traced();
  s.spans_total = p.spans_total();
  s.spans_ray_traced = p.spans_ray_traced();
  if (!p.shadow_method().empty()) s.shadow_method = p.shadow_method();
  return s;
}

v1::JobState ToProto(farm::JobState s) {
  switch (s) {
    case farm::JobState::kQueued:
      return v1::JOB_STATE_QUEUED;
    case farm::JobState::kRunning:
      return v1::JOB_STATE_RUNNING;
    case farm::JobState::kSucceeded:
      return v1::JOB_STATE_SUCCEEDED;
    case farm::JobState::kFailed:
      return v1::JOB_STATE_FAILED;
    case farm::JobState::kCancelled:
      return v1::JOB_STATE_CANCELLED;
  }
  return v1::JOB_STATE_UNSPECIFIED;
}

farm::JobState FromProto(v1::JobState s) {
  switch (s) {
    case v1::JOB_STATE_RUNNING:
      return farm::JobState::kRunning;
    case v1::JOB_STATE_SUCCEEDED:
      return farm::JobState::kSucceeded;
    case v1::JOB_STATE_FAILED:
      return farm::JobState::kFailed;
    case v1::JOB_STATE_CANCELLED:
      return farm::JobState::kCancelled;
    default:
      return farm::JobState::kQueued;
  }
}

v1::JobStatus ToProto(const farm::JobInfo& j) {
  v1::JobStatus p;
  p.set_job_id(j.job_id);
  p.set_state(ToProto(j.state));
  p.set_scene_name(j.spec.scene_name);
  p.set_output(j.spec.output);
  p.set_width(j.spec.width);
  p.set_height(j.spec.height);
  p.set_frame_first(j.spec.frame_first);
  p.set_frame_last(j.spec.frame_last);
  p.set_bands_per_frame(j.spec.bands);
  p.set_bands_total(j.spec.bands_total());
  p.set_bands_done(j.bands_done);
  p.set_frames_total(j.spec.frames());
  p.set_frames_done(j.frames_done);
  p.set_error(j.error);
  p.set_seconds_elapsed(j.seconds_elapsed);
  *p.mutable_stats() = ToProto(j.stats);
  for (int f : j.frames_written) p.add_frames_written(f);
  p.set_results_discarded(j.results_discarded);
  p.set_speculative_leases(j.speculative_leases);
  for (const std::string& w : j.quarantined) p.add_quarantined_workers(w);
  return p;
}

farm::JobInfo FromProto(const v1::JobStatus& p) {
  farm::JobInfo j;
  j.job_id = p.job_id();
  j.state = FromProto(p.state());
  j.spec.scene_name = p.scene_name();
  j.spec.output = p.output();
  j.spec.width = p.width();
  j.spec.height = p.height();
  j.spec.frame_first = p.frame_first();
  j.spec.frame_last = p.frame_last();
  j.spec.bands = p.bands_per_frame();
  j.bands_done = p.bands_done();
  j.frames_done = p.frames_done();
  j.error = p.error();
  j.seconds_elapsed = p.seconds_elapsed();
  j.stats = FromProto(p.stats());
  j.frames_written.assign(p.frames_written().begin(), p.frames_written().end());
  j.results_discarded = p.results_discarded();
  j.speculative_leases = p.speculative_leases();
  j.quarantined.assign(p.quarantined_workers().begin(), p.quarantined_workers().end());
  return j;
}

v1::WorkerInfo ToProto(const farm::WorkerInfo& w) {
  v1::WorkerInfo p;
  p.set_worker_id(w.worker_id);
  p.set_name(w.name);
  p.set_threads(w.threads);
  p.set_state(w.busy ? "busy" : "idle");
  p.set_job_id(w.job_id);
  p.set_frame(w.frame);
  p.set_band(w.band);
  p.set_bands_done(w.bands_done);
  p.set_seconds_since_seen(w.seconds_since_seen);
  return p;
}

farm::WorkerInfo FromProto(const v1::WorkerInfo& p) {
  farm::WorkerInfo w;
  w.worker_id = p.worker_id();
  w.name = p.name();
  w.threads = p.threads();
  w.busy = p.state() == "busy";
  w.job_id = p.job_id();
  w.frame = p.frame();
  w.band = p.band();
  w.bands_done = p.bands_done();
  w.seconds_since_seen = p.seconds_since_seen();
  return w;
}

v1::BandTask ToProto(const farm::BandTask& t) {
  v1::BandTask p;
  p.set_lease_id(t.lease_id);
  p.set_lease_ms(t.lease_remaining.count());
  p.set_job_id(t.job_id);
  p.set_scene_hash(t.scene_hash);
  p.set_frame(t.frame);
  p.set_band(t.band);
  p.set_y0(t.y0);
  p.set_y1(t.y1);
  p.set_width(t.width);
  p.set_height(t.height);
  *p.mutable_render() = ToProto(t.render);
  p.set_orbit_degrees(t.orbit_degrees);
  p.set_frame_first(t.frame_first);
  p.set_frame_last(t.frame_last);
  return p;
}

farm::BandTask FromProto(const v1::BandTask& p) {
  farm::BandTask t;
  t.lease_id = p.lease_id();
  t.lease_remaining = farm::Millis(p.lease_ms());
  t.job_id = p.job_id();
  t.scene_hash = p.scene_hash();
  t.frame = p.frame();
  t.band = p.band();
  t.y0 = p.y0();
  t.y1 = p.y1();
  t.width = p.width();
  t.height = p.height();
  t.render = FromProto(p.render());
  t.orbit_degrees = p.orbit_degrees();
  t.frame_first = p.frame_first();
  t.frame_last = p.frame_last();
  return t;
}

farm::SubmitRequest FromProto(const v1::JobSpec& p) {
  farm::SubmitRequest r;
  r.scene = p.scene();
  r.scene_name = p.scene_name();
  r.render = FromProto(p.render());
  r.width = p.width();
  r.height = p.height();
  r.frame_first = p.frame_first();
  r.frame_last = p.frame_last();
  r.bands = p.bands();
  r.output = p.output();
  r.orbit_degrees = p.orbit_degrees();
  return r;
}

v1::JobSpec ToProto(const farm::SubmitRequest& r) {
  v1::JobSpec p;
  *p.mutable_scene() = r.scene;
  p.set_scene_name(r.scene_name);
  *p.mutable_render() = ToProto(r.render);
  p.set_width(r.width);
  p.set_height(r.height);
  p.set_frame_first(r.frame_first);
  p.set_frame_last(r.frame_last);
  p.set_bands(r.bands);
  p.set_output(r.output);
  p.set_orbit_degrees(r.orbit_degrees);
  return p;
}

v1::CompleteBandRequest ToProto(farm::BandOutput&& o) {
  v1::CompleteBandRequest p;
  p.set_worker_id(o.worker_id);
  p.set_lease_id(o.lease_id);
  p.mutable_rgb()->Add(o.rgb.begin(), o.rgb.end());
  o.rgb.clear();
  o.rgb.shrink_to_fit();
  *p.mutable_stats() = ToProto(o.stats);
  p.set_error(o.error);
  p.set_handed_back(o.handed_back);
  return p;
}

farm::BandOutput FromProto(const v1::CompleteBandRequest& p) {
  farm::BandOutput o;
  o.worker_id = p.worker_id();
  o.lease_id = p.lease_id();
  o.rgb.assign(p.rgb().begin(), p.rgb().end());
  o.stats = FromProto(p.stats());
  o.error = p.error();
  o.handed_back = p.handed_back();
  return o;
}

}  // namespace locus::rpc
