#include "server/notifier.h"

#include <google/protobuf/util/json_util.h>
#include <httplib.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "common/farm/process.h"
#include "proto/wire/rpc.h"
#include "server/submission.h"

namespace locus::rpc {
namespace {

using Clock = std::chrono::steady_clock;

// Debian's bundle of the public CAs (package ca-certificates), for https.
constexpr const char* kSystemCas = "/etc/ssl/certs/ca-certificates.crt";

}  // namespace

Notifier::Notifier(farm::Coordinator& coordinator, NotifierOptions options)
    : coordinator_(coordinator), options_(std::move(options)) {
  coordinator_.on_job_ended([this](const farm::JobInfo& job) { enqueue(job); },
                            !options_.command.empty());
  thread_ = std::thread([this] { loop(); });
}

Notifier::~Notifier() {
  coordinator_.on_job_ended(nullptr, false);
  {
    std::lock_guard lk(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::string Notifier::body(const farm::JobInfo& job) {
  google::protobuf::util::JsonPrintOptions o;
  o.always_print_primitive_fields = true;
  o.preserve_proto_field_names = true;
  std::string out;
  if (!google::protobuf::util::MessageToJsonString(ToProto(job), &out, o).ok()) {
    out = "{\"job_id\":\"" + job.job_id + "\",\"state\":\"" + farm::job_state_name(job.state) +
          "\"}";
  }
  return out;
}

Status Notifier::post(const std::string& url, const std::string& body,
                      std::chrono::milliseconds timeout) {
  auto u = farm::parse_http_url(url, "notify URL");
  if (!u.ok()) return u.status();
  const std::string host = u->host.find(':') != std::string::npos ? "[" + u->host + "]" : u->host;
  const std::string origin =
      std::string(u->https ? "https://" : "http://") + host + ":" + std::to_string(u->port);
  httplib::Client client(origin);
  const time_t secs = std::max<time_t>(1, timeout.count() / 1000);
  client.set_connection_timeout(secs, 0);
  client.set_read_timeout(secs, 0);
  client.set_write_timeout(secs, 0);
  client.set_follow_location(false);  // the allowed URL, not wherever it points
  if (u->https && std::filesystem::exists(kSystemCas)) client.set_ca_cert_path(kSystemCas);
  const httplib::Headers headers = {{"User-Agent", "locus-coordinator"},
                                    {"X-Locus-Event", "job-ended"}};
  auto res = client.Post(u->path, headers, body, "application/json");
  if (!res) return Status(Code::kUnavailable, httplib::to_string(res.error()));
  if (res->status < 200 || res->status > 299) {
    return Status(Code::kUnavailable, "HTTP " + std::to_string(res->status));
  }
  return Status::Ok();
}

void Notifier::enqueue(const farm::JobInfo& job) {
  {
    std::lock_guard lk(mu_);
    queue_.push_back(Pending{job, 0, options_.command.empty(), Clock::now()});
  }
  cv_.notify_all();
}

Status Notifier::run_command(const farm::JobInfo& job) {
  char tmpl[] = "/tmp/locus-notify-XXXXXX";
  const int fd = ::mkstemp(tmpl);
  if (fd >= 0) ::close(fd);
  farm::ProcessRun run;
  run.argv = {"/bin/sh", "-c", options_.command};
  run.env = {{"LOCUS_JOB_ID", job.job_id},
             {"LOCUS_JOB_STATE", farm::job_state_name(job.state)},
             {"LOCUS_JOB_KIND", std::string(label_name(farm::kJobKindLabels, job.spec.kind))},
             {"LOCUS_JOB_OWNER", job.spec.owner},
             {"LOCUS_JOB_ERROR", job.error},
             {"LOCUS_JOB_DIR", coordinator_.job_dir(job.job_id)}};
  run.output_path = fd >= 0 ? tmpl : "";
  run.timeout = options_.command_timeout;
  run.cancelled = [this] {
    std::lock_guard lk(mu_);
    return stopping_;
  };
  auto ran = farm::run_process(run);
  if (fd >= 0) std::remove(tmpl);
  if (!ran.ok()) return ran.status();
  if (ran->exit_code != 0) {
    return Status(Code::kInternal,
                  (ran->exit_code > 0 ? "exited with status " + std::to_string(ran->exit_code)
                                      : "killed by signal " + std::to_string(ran->signal)) +
                      (ran->last_line.empty() ? "" : ": " + ran->last_line));
  }
  return Status::Ok();
}

bool Notifier::step(Pending& p) {
  const std::string& id = p.job.job_id;
  if (!p.command_done) {
    p.command_done = true;
    const Status s = run_command(p.job);
    coordinator_.record_notified(
        id, s.ok() ? "notify command done" : "notify command failed: " + s.message(), false);
    if (!s.ok()) spdlog::warn("job {}: notify command failed: {}", id, s.message());
  }
  const std::string& url = p.job.spec.notify_url;
  if (url.empty()) return true;
  ++p.attempt;
  const Status s = post(url, body(p.job), options_.timeout);
  if (s.ok()) {
    coordinator_.record_notified(id, "notified " + url, false);
    return true;
  }
  if (p.attempt >= options_.attempts) {
    coordinator_.record_notified(id,
                                 "gave up notifying " + url + " after " +
                                     std::to_string(p.attempt) + " attempts: " + s.message(),
                                 false);
    spdlog::warn("job {}: gave up notifying {}: {}", id, url, s.message());
    return true;
  }
  const auto wait = options_.first_backoff * (1LL << std::min(p.attempt - 1, 12));
  coordinator_.record_notified(
      id,
      "notifying " + url + " failed (attempt " + std::to_string(p.attempt) + " of " +
          std::to_string(options_.attempts) + "): " + s.message() + "; again in " +
          std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(wait).count()) +
          " ms",
      false);
  p.due = Clock::now() + wait;
  return false;
}

void Notifier::loop() {
  std::unique_lock lk(mu_);
  while (!stopping_) {
    // The notice due first.
    auto it = std::min_element(queue_.begin(), queue_.end(),
                               [](const Pending& a, const Pending& b) { return a.due < b.due; });
    if (it == queue_.end()) {
      cv_.wait(lk);
      continue;
    }
    if (it->due > Clock::now()) {
      cv_.wait_until(lk, it->due);
      continue;
    }
    Pending p = std::move(*it);
    queue_.erase(it);
    lk.unlock();
    const bool done = step(p);
    if (done) coordinator_.record_notified(p.job.job_id, "", true);
    lk.lock();
    if (!done) queue_.push_back(std::move(p));
  }
}

}  // namespace locus::rpc
