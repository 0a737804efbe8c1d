#include "proto/wire/rpc.h"

#include <absl/synchronization/mutex.h>
#include <arpa/inet.h>

#include <fstream>
#include <sstream>

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
      return Status(Code::kPermissionDenied,
                    "the " + peer + " refused the call (PERMISSION_DENIED): " + s.error_message());
    case G::UNAUTHENTICATED:
      return Status(Code::kUnauthenticated,
                    "the " + peer + " refused the call (UNAUTHENTICATED): " + s.error_message());
    case G::UNAVAILABLE: {
      // A TLS mismatch shows only as a failed connection; say where to look.
      const std::string& m = s.error_message();
      const bool tls = m.find("andshake") != std::string::npos ||
                       m.find("SSL") != std::string::npos || m.find("ssl") != std::string::npos ||
                       m.find("Socket closed") != std::string::npos;
      return Status(Code::kUnavailable,
                    "cannot reach the " + peer + " (" + m +
                        "); is it running, and is the address right?" +
                        (tls ? " If the farm uses TLS, give --tls-ca with the CA that signed its "
                               "certificate (and --tls-cert/--tls-key for mutual TLS)."
                             : ""));
    }
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

namespace {

Result<std::string> read_pem(const std::string& path, const std::string& flag) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return FailedPrecondition(flag + " " + path + ": cannot read the file");
  std::ostringstream text;
  text << in.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos)
    return InvalidArgument(flag + " " + path + ": not a PEM file (no -----BEGIN line)");
  return text.str();
}

grpc::ChannelArguments channel_arguments() {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(farm::kMaxMessageBytes);
  args.SetMaxSendMessageSize(farm::kMaxMessageBytes);
  // Reconnect quickly after a coordinator restart rather than backing off
  // for minutes.
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
  return args;
}

}  // namespace

bool is_loopback(const std::string& address) {
  std::string a = address;
  if (a.rfind("unix:", 0) == 0) return true;
  for (const char* scheme : {"ipv4:", "ipv6:", "dns:///", "dns:"}) {
    if (a.rfind(scheme, 0) == 0) {
      a = a.substr(std::string(scheme).size());
      break;
    }
  }
  std::string host;
  if (!a.empty() && a[0] == '[') {
    const size_t close = a.find(']');
    if (close == std::string::npos) return false;
    host = a.substr(1, close - 1);
  } else {
    host = a.substr(0, a.rfind(':'));
  }
  if (host == "localhost" || host == "::1") return true;
  in_addr v4{};
  return inet_pton(AF_INET, host.c_str(), &v4) == 1 && (ntohl(v4.s_addr) >> 24) == 127;
}

Result<Connection> connect(const std::string& address, const farm::Credentials& c) {
  Connection conn;
  conn.token = c.token;
  conn.address = address;
  if (c.tls_cert.empty() != c.tls_key.empty())
    return InvalidArgument(
        "--tls-cert and --tls-key go together (a client certificate and its key)");
  std::shared_ptr<grpc::ChannelCredentials> creds;
  if (!c.tls_ca.empty() || !c.tls_cert.empty()) {
    grpc::SslCredentialsOptions ssl;
    if (!c.tls_ca.empty()) {
      auto ca = read_pem(c.tls_ca, "--tls-ca");
      if (!ca.ok()) return ca.status();
      ssl.pem_root_certs = *ca;
    }
    if (!c.tls_cert.empty()) {
      auto cert = read_pem(c.tls_cert, "--tls-cert");
      if (!cert.ok()) return cert.status();
      auto key = read_pem(c.tls_key, "--tls-key");
      if (!key.ok()) return key.status();
      ssl.pem_cert_chain = *cert;
      ssl.pem_private_key = *key;
    }
    creds = grpc::SslCredentials(ssl);
  } else if (c.insecure || is_loopback(address)) {
    creds = grpc::InsecureChannelCredentials();
  } else {
    return FailedPrecondition("farm at " + address +
                              ": give --tls-ca CA.pem to reach it over TLS, or --insecure for "
                              "plaintext on a trusted network (plaintext is the default only on "
                              "loopback addresses)");
  }
  conn.channel = grpc::CreateCustomChannel(address, creds, channel_arguments());
  return conn;
}

void prepare(grpc::ClientContext& context, const Connection& connection, farm::Millis timeout) {
  context.set_deadline(std::chrono::system_clock::now() + timeout);
  if (!connection.token.empty()) context.AddMetadata("authorization", "Bearer " + connection.token);
}

Status check_server_security(const ServerSecurity& s) {
  if (s.tls_cert.empty() != s.tls_key.empty())
    return InvalidArgument(
        "--tls-cert and --tls-key go together (the server certificate and its key)");
  if (!s.tls_ca.empty() && s.tls_cert.empty())
    return InvalidArgument("--tls-ca (mutual TLS) needs --tls-cert and --tls-key as well");
  if (s.tls_cert.empty() && !s.insecure) {
    return FailedPrecondition(
        "refusing to serve without TLS: give --tls-cert and --tls-key (docs/farm.md "
        "\"Security\"), or --insecure to serve plaintext on a trusted network");
  }
  if (!s.auth.enforcing() && !s.insecure) {
    return FailedPrecondition(
        "refusing to serve without tokens: give --client-tokens FILE and --worker-tokens FILE "
        "(one token per line), or --insecure to let anyone who reaches the port use the farm");
  }
  return Status::Ok();
}

void configure_server(grpc::ServerBuilder& builder) {
  // Debian's Abseil checks every lock gRPC takes for deadlock cycles (a
  // graph of lock orders kept up to date on each acquisition): about 5% of
  // the coordinator's CPU at a thousand workers (docs/farm.md "The farm at
  // scale"). A debugging aid, off here as in release builds of Abseil.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
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

// ---------------------------------------------------------------- conversions

v1::RenderSettings ToProto(const farm::RenderSettings& s) {
  v1::RenderSettings p;
  p.set_method(s.method);
  p.set_boxes(s.boxes);
  p.set_spp(s.spp);
  p.set_aa(s.aa);
  p.set_tess_tol(s.tess_tol);
  return p;
}

farm::RenderSettings FromProto(const v1::RenderSettings& p) {
  farm::RenderSettings s;
  s.method = p.method().empty() ? farm::RenderSettings{}.method : p.method();
  s.boxes = p.boxes().empty() ? farm::RenderSettings{}.boxes : p.boxes();
  s.spp = p.spp() == 0 ? 1 : p.spp();
  s.aa = p.has_aa() ? p.aa() : farm::RenderSettings{}.aa;
  s.tess_tol = p.has_tess_tol() ? p.tess_tol() : farm::RenderSettings{}.tess_tol;
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
  p.set_seconds_tessellate(s.seconds_tessellate);
  p.set_geometry_triangles(s.geometry_triangles);
  p.set_seconds_render_cpu(s.seconds_render_cpu);
  p.set_pixels_total(s.pixels_total);
  p.set_pixels_ray_traced(s.pixels_ray_traced);
  p.set_spans_total(s.spans_total);
  p.set_spans_ray_traced(s.spans_ray_traced);
  p.set_shadow_method(s.shadow_method);
  p.set_visibility(s.visibility);
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
  s.seconds_tessellate = p.seconds_tessellate();
  s.geometry_triangles = p.geometry_triangles();
  s.seconds_render_cpu = p.seconds_render_cpu();
  s.pixels_total = p.pixels_total();
  s.pixels_ray_traced = p.pixels_ray_traced();
  s.spans_total = p.spans_total();
  s.spans_ray_traced = p.spans_ray_traced();
  if (!p.shadow_method().empty()) s.shadow_method = p.shadow_method();
  if (!p.visibility().empty()) s.visibility = p.visibility();
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
    case farm::JobState::kPaused:
      return v1::JOB_STATE_PAUSED;
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
    case v1::JOB_STATE_PAUSED:
      return farm::JobState::kPaused;
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
  p.set_priority(j.spec.priority);
  p.set_owner(j.spec.owner);
  p.set_frame_order(std::string(label_name(farm::kFrameOrderLabels, j.spec.frame_order)));
  p.set_band_timeout_ms(j.spec.band_timeout.count());
  p.set_bands_timed_out(j.bands_timed_out);
  p.set_bands_running(j.bands_running);
  for (const std::string& t : j.spec.require) p.add_require(t);
  for (const std::string& a : j.spec.after) p.add_after(a);
  p.set_waiting(j.waiting);
  p.set_band_seconds(j.account.done);
  p.set_band_seconds_failed(j.account.failed);
  p.set_band_seconds_lost(j.account.lost);
  p.set_kind(std::string(label_name(farm::kJobKindLabels, j.spec.kind)));
  p.set_movie(j.spec.kind == farm::JobKind::kMovie ? j.spec.output : j.spec.movie);
  p.set_fps(j.spec.fps);
  p.set_movie_job(j.movie_job);
  p.set_notify_url(j.spec.notify_url);
  p.set_cost_map(j.spec.cost_map);
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
  j.spec.priority = p.priority();
  j.spec.owner = p.owner();
  j.spec.frame_order =
      label_value(farm::kFrameOrderLabels, p.frame_order()).value_or(farm::FrameOrder::kInOrder);
  j.spec.band_timeout = farm::Millis(p.band_timeout_ms());
  j.bands_timed_out = p.bands_timed_out();
  j.bands_running = p.bands_running();
  j.spec.require.assign(p.require().begin(), p.require().end());
  j.spec.after.assign(p.after().begin(), p.after().end());
  j.waiting = p.waiting();
  j.account = {p.band_seconds(), p.band_seconds_failed(), p.band_seconds_lost()};
  j.spec.kind = label_value(farm::kJobKindLabels, p.kind()).value_or(farm::JobKind::kRender);
  if (j.spec.kind == farm::JobKind::kRender) j.spec.movie = p.movie();
  j.spec.fps = p.fps();
  j.movie_job = p.movie_job();
  j.spec.notify_url = p.notify_url();
  j.spec.cost_map = p.cost_map();
  return j;
}

v1::WorkerInfo ToProto(const farm::WorkerInfo& w) {
  v1::WorkerInfo p;
  p.set_worker_id(w.worker_id);
  p.set_name(w.name);
  p.set_threads(w.threads);
  p.set_state(farm::worker_state_name(w));
  p.set_job_id(w.job_id);
  p.set_frame(w.frame);
  p.set_band(w.band);
  p.set_bands_done(w.bands_done);
  p.set_seconds_since_seen(w.seconds_since_seen);
  for (const std::string& t : w.tags) p.add_tags(t);
  return p;
}

v1::BandLogLine ToProto(const farm::BandLogLine& l) {
  v1::BandLogLine p;
  p.set_seq(l.seq);
  p.set_frame(l.frame);
  p.set_band(l.band);
  p.set_lease_id(l.lease_id);
  p.set_worker_id(l.worker_id);
  p.set_text(l.text);
  return p;
}

v1::Attempt ToProto(const farm::AttemptInfo& a) {
  v1::Attempt p;
  p.set_lease_id(a.lease_id);
  p.set_job_id(a.job_id);
  p.set_frame(a.frame);
  p.set_band(a.band);
  p.set_worker_id(a.worker_id);
  p.set_worker_name(a.worker_name);
  p.set_speculative(a.speculative);
  p.set_started_at(a.started_at);
  p.set_ended_at(a.ended_at);
  p.set_outcome(a.outcome);
  p.set_error(a.error);
  return p;
}

v1::FrameStatus ToProto(const farm::FrameDetail& f) {
  v1::FrameStatus p;
  p.set_job_id(f.job_id);
  p.set_frame(f.frame);
  p.set_width(f.width);
  p.set_height(f.height);
  p.set_written(f.written);
  p.set_file_name(f.file_name);
  for (const farm::BandDetail& b : f.bands) {
    v1::BandStatus* q = p.add_bands();
    q->set_band(b.band);
    q->set_y0(b.y0);
    q->set_y1(b.y1);
    q->set_state(b.state);
    q->set_predicted_cost(b.predicted_cost);
    *q->mutable_stats() = ToProto(b.stats);
    q->set_seconds(b.seconds);
    q->set_worker_id(b.worker_id);
    q->set_worker_name(b.worker_name);
    for (const farm::AttemptInfo& a : b.attempts) *q->add_attempts() = ToProto(a);
  }
  for (float c : f.row_costs) p.add_row_costs(c);
  return p;
}

v1::WorkerStatus ToProto(const farm::WorkerDetail& w) {
  v1::WorkerStatus p;
  if (w.info) *p.mutable_info() = ToProto(*w.info);
  p.set_worker_id(w.worker_id);
  for (const farm::AttemptInfo& a : w.attempts) *p.add_attempts() = ToProto(a);
  for (const farm::BandLogLine& l : w.logs) *p.add_logs() = ToProto(l);
  return p;
}

farm::WorkerInfo FromProto(const v1::WorkerInfo& p) {
  farm::WorkerInfo w;
  w.worker_id = p.worker_id();
  w.name = p.name();
  w.threads = p.threads();
  w.busy = p.state() == "busy" || !p.job_id().empty();
  w.draining = p.state() == "draining";
  w.disabled = p.state() == "disabled";
  w.job_id = p.job_id();
  w.frame = p.frame();
  w.band = p.band();
  w.bands_done = p.bands_done();
  w.seconds_since_seen = p.seconds_since_seen();
  w.tags.assign(p.tags().begin(), p.tags().end());
  return w;
}

v1::BandTask ToProto(const farm::BandLease& t) {
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
  p.set_encoding(static_cast<v1::BandEncoding>(t.encoding));
  p.set_cost_map(t.cost_map);
  return p;
}

farm::BandLease FromProto(const v1::BandTask& p) {
  farm::BandLease t;
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
  t.encoding = static_cast<farm::BandEncoding>(p.encoding());
  t.cost_map = p.cost_map();
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
  if (p.has_priority()) r.priority = p.priority();
  r.frame_order = p.frame_order();
  r.band_timeout = farm::Millis(p.band_timeout_ms());
  r.require.assign(p.require().begin(), p.require().end());
  r.after.assign(p.after().begin(), p.after().end());
  r.movie = p.movie();
  r.fps = p.fps();
  r.notify_url = p.notify_url();
  r.cost_map = p.cost_map();
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
  p.set_priority(r.priority);
  p.set_frame_order(r.frame_order);
  p.set_band_timeout_ms(r.band_timeout.count());
  for (const std::string& t : r.require) p.add_require(t);
  for (const std::string& a : r.after) p.add_after(a);
  p.set_movie(r.movie);
  p.set_fps(r.fps);
  p.set_notify_url(r.notify_url);
  p.set_cost_map(r.cost_map);
  return p;
}

v1::CompleteBandRequest ToProto(farm::BandOutput&& o) {
  v1::CompleteBandRequest p;
  p.set_worker_id(o.worker_id);
  p.set_lease_id(o.lease_id);
  p.mutable_rgb()->Add(o.rgb.begin(), o.rgb.end());
  o.rgb.clear();
  o.rgb.shrink_to_fit();
  if (!o.encoded.bytes.empty()) {
    p.set_encoding(static_cast<v1::BandEncoding>(o.encoded.encoding));
    p.set_width(o.encoded.width);
    p.set_rows(o.encoded.rows);
    *p.mutable_pixels() = std::move(o.encoded.bytes);
  }
  *p.mutable_stats() = ToProto(o.stats);
  *p.mutable_cost() = std::move(o.cost);
  p.set_error(o.error);
  p.set_handed_back(o.handed_back);
  for (const std::string& l : o.log_lines) p.add_log_lines(l);
  return p;
}

farm::BandOutput FromProto(const v1::CompleteBandRequest& p) {
  farm::BandOutput o;
  o.worker_id = p.worker_id();
  o.lease_id = p.lease_id();
  o.rgb.assign(p.rgb().begin(), p.rgb().end());
  // Still encoded: the coordinator decodes (decode_band) where it can refuse.
  o.encoded.encoding = static_cast<farm::BandEncoding>(p.encoding());
  o.encoded.width = p.width();
  o.encoded.rows = p.rows();
  o.encoded.bytes = p.pixels();
  o.stats = FromProto(p.stats());
  o.cost = p.cost();
  o.error = p.error();
  o.handed_back = p.handed_back();
  o.log_lines.assign(p.log_lines().begin(), p.log_lines().end());
  return o;
}

v1::FileChunk ToProto(const farm::FileChunk& c) {
  v1::FileChunk p;
  p.set_frame(c.frame);
  p.set_file_name(c.file_name);
  p.set_offset(c.offset);
  p.set_data(c.data);
  p.set_last(c.last);
  return p;
}

farm::FileChunk FromProto(v1::FileChunk&& p) {
  farm::FileChunk c;
  c.frame = p.frame();
  c.file_name = p.file_name();
  c.offset = p.offset();
  c.data = std::move(*p.mutable_data());
  c.last = p.last();
  return c;
}

}  // namespace locus::rpc
