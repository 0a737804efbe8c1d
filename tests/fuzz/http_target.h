// The HTTP API fuzzer's body (fuzz_http.cpp), also replayed on the corpus by
// the gtest suite (tests/fuzz_corpus_test.cpp). Each input is a sequence of
// HTTP requests as HttpApi takes them (server/http_api.h), separated by a
// NUL byte: a first line "METHOD PATH[?QUERY]", header lines "Name: value"
// (Authorization, Content-Type, Origin, Host, X-Remote), an empty line, and
// the body. In front: a fresh Coordinator with one job of user ann, tokens
// for ann ("fuzz-ann"), bob ("fuzz-bob") and an admin ("fuzz-root"). Every
// request must get an answer with a status in [200, 599] and, for the API,
// a JSON body; afterwards the coordinator must still answer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "common/scene/scene_io.h"
#include "proto/wire/rpc.h"
#include "server/coordinator.h"
#include "server/handlers.h"
#include "server/http_api.h"
#include "tests/fuzz/fuzz_util.h"

namespace locus::fuzz {
namespace http_target {

inline rpc::HttpRequest parse(const std::string& text) {
  rpc::HttpRequest r;
  const size_t head_end = text.find("\n\n");
  const std::string head = text.substr(0, head_end);
  r.body = head_end == std::string::npos ? "" : text.substr(head_end + 2);
  size_t at = 0;
  bool first = true;
  while (at <= head.size()) {
    size_t nl = head.find('\n', at);
    if (nl == std::string::npos) nl = head.size();
    const std::string line = head.substr(at, nl - at);
    at = nl + 1;
    if (first) {
      first = false;
      const size_t sp = line.find(' ');
      r.method = line.substr(0, sp);
      const std::string target = sp == std::string::npos ? "" : line.substr(sp + 1);
      const size_t q = target.find('?');
      r.path = target.substr(0, q);
      r.query = q == std::string::npos ? "" : target.substr(q + 1);
      continue;
    }
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string value = line.substr(colon + 1);
    if (!value.empty() && value[0] == ' ') value.erase(0, 1);
    const std::string name = line.substr(0, colon);
    if (name == "Authorization") r.authorization = value;
    if (name == "Content-Type") r.content_type = value;
    if (name == "Origin") r.origin = value;
    if (name == "Host") r.host = value;
    if (name == "X-Remote") r.remote = value;
  }
  if (r.remote.empty()) r.remote = "127.0.0.1";
  return r;
}

inline void check(const rpc::HttpResponse& r, const rpc::HttpRequest& req) {
  if (r.status < 200 || r.status > 599) violated("HTTP status " + std::to_string(r.status));
  const bool api = req.path.rfind("/api/", 0) == 0;
  if (api && r.file.empty() && r.content_type == "application/json" &&
      (r.body.empty() || r.body[0] != '{')) {
    violated("an API answer that is not a JSON object: " + r.body.substr(0, 80));
  }
  if (api && r.status == 401 && r.body.find("\"jobs\"") != std::string::npos)
    violated("job data without a token");
  bool csp = false;
  for (const auto& [n, v] : r.headers) csp |= n == "Content-Security-Policy";
  if (!csp) violated("an answer without a Content-Security-Policy");
}

}  // namespace http_target

inline int fuzz_http(const uint8_t* data, size_t size) {
  using namespace http_target;
  quiet_logs();
  farm::CoordinatorOptions o;
  o.group_commit = farm::Millis(0);  // each accepted band synced at once: no waiting per input
  o.data_dir = scratch_dir() + "/http";
  std::error_code ec;
  std::filesystem::remove_all(o.data_dir, ec);  // each input on a fresh farm
  o.limits.max_resolution = 64;
  o.limits.max_jobs = 4;
  farm::Coordinator coordinator(o);
  if (!coordinator.start().ok()) violated("the coordinator did not start");
  rpc::Handlers handlers(coordinator);
  const farm::Authenticator auth = farm::Authenticator::from_tokens(
      {"ann fuzz-ann", "bob fuzz-bob"}, {"fuzz-worker"}, {"root fuzz-root"});
  rpc::HttpOptions options;
  options.reuse = std::chrono::milliseconds(0);  // every request reaches the handlers
  rpc::HttpApi api(coordinator, handlers, auth, options);
  // One job of ann's: a sphere, two frames of two bands.
  {
    Scene scene;
    scene.camera.from = Vec3(0, 0, 5);
    scene.camera.width = 8;
    scene.camera.height = 6;
    scene.has_camera = true;
    scene.materials.push_back(Material{});
    Object sphere;
    sphere.shape = Sphere{Vec3(0, 0, 0), 1.0};
    scene.objects.push_back(sphere);
    Light light;
    light.position = Vec3(3, 3, 3);
    scene.lights.push_back(light);
    farm::SubmitRequest r;
    r.scene = scene_to_proto(scene);
    r.scene_name = "fuzz";
    r.width = 8;
    r.height = 6;
    r.frame_first = 1;
    r.frame_last = 2;
    r.bands = 2;
    r.output = "f_####.png";
    auto job = coordinator.submit(r, "ann");
    if (!job.ok()) violated("the fuzz job was refused: " + job.status().message());
  }
  size_t at = 0;
  const std::string input(reinterpret_cast<const char*>(data), size);
  for (int n = 0; at <= input.size() && n < 64; ++n) {
    size_t end = input.find('\0', at);
    if (end == std::string::npos) end = input.size();
    const rpc::HttpRequest req = parse(input.substr(at, end - at));
    at = end + 1;
    check(api.handle(req), req);
  }
  rpc::HttpRequest alive;
  alive.method = "GET";
  alive.path = "/api/v1/jobs";
  alive.authorization = "Bearer fuzz-root";
  alive.remote = "10.9.9.9";  // not rate-limited by the input's requests
  const rpc::HttpResponse r = api.handle(alive);
  if (r.status != 200) violated("the API stopped answering: " + r.body.substr(0, 120));
  coordinator.shutdown();
  return 0;
}

}  // namespace locus::fuzz
