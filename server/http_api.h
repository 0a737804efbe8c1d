// The coordinator's HTTP face (issue #24): the dashboard's pages and its
// JSON API, as a plain function of a request: no sockets (the cpp-httplib
// adapter is server/http_server.cpp), so tests and the fuzzer call it
// directly. Every API route is a ClientService RPC: its request message is
// built from the path, the query and the JSON body, handed to the same
// Handlers as gRPC (server/handlers.h: one implementation of the rules),
// and the response message printed in proto3's JSON mapping with the field
// names of proto/locus.proto. Images (frames, thumbnails, bands of a frame
// in progress) are PNG files. docs/http-api.md lists the routes.
#pragma once

#include <chrono>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "common/farm/auth.h"
#include "server/coordinator.h"
#include "server/handlers.h"

namespace locus::rpc {

struct HttpRequest {
  std::string method;         // "GET", "POST", ...
  std::string path;           // "/api/v1/jobs/j0001", already %-decoded
  std::string query;          // "after=12&frame=3", not decoded
  std::string authorization;  // the header's value
  std::string content_type;
  std::string origin;  // the Origin header, when the browser sent one
  std::string host;    // the Host header
  std::string body;
  std::string remote;  // the peer's address, for the rate limit
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  // When set, the body is this file's contents (the adapter sends it).
  std::string file;
  std::vector<std::pair<std::string, std::string>> headers;
};

struct HttpOptions {
  // Requests per second per peer address (a token bucket of `burst`);
  // past it 429. A dashboard makes 1 to 3 per second.
  double rate = 200;
  double burst = 400;
  size_t max_body = 64 * 1024;
  size_t max_path = 2048;
  int thumbnail_width = 160;  // thumbnails are at most this wide
  // The farm's snapshot and a job's status, as JSON, are reused for this
  // long by every watcher of the same user (a page polls once a second):
  // 200 dashboards cost a few snapshots a second, not 200. An action
  // through the API forgets them at once.
  std::chrono::milliseconds reuse{250};
};

class HttpApi {
 public:
  using Clock = std::chrono::steady_clock;
  HttpApi(farm::Coordinator& coordinator, Handlers& handlers, const farm::Authenticator& auth,
          HttpOptions options = {});

  // Never throws; every error is a response (JSON `{"error": {...}}` for
  // the API). Thread-safe.
  HttpResponse handle(const HttpRequest& request);
  const HttpOptions& options() const { return options_; }

  // The headers every response carries: a Content-Security-Policy without
  // inline scripts, no sniffing, no framing, no referrer.
  static const std::vector<std::pair<std::string, std::string>>& security_headers();

 private:
  HttpResponse route(const HttpRequest& request, const std::vector<std::string>& parts,
                     const farm::Caller& caller);
  HttpResponse image(const std::vector<std::string>& parts, const farm::Caller& caller);
  // An image made for this request, as a PNG tagged for display.
  HttpResponse png_now(const Image& image);
  bool allow(const std::string& remote);
  // The answer under `key` if made less than options_.reuse ago, else
  // `make`'s (kept when it succeeded).
  HttpResponse reused(const std::string& key, const std::function<HttpResponse()>& make);

  farm::Coordinator& c_;
  Handlers& h_;
  const farm::Authenticator& auth_;
  HttpOptions options_;
  std::mutex rate_mu_;
  struct Bucket {
    double tokens = 0;
    Clock::time_point at;
  };
  std::map<std::string, Bucket> buckets_;
  std::mutex reuse_mu_;
  struct Kept {
    HttpResponse response;
    Clock::time_point at;
  };
  std::map<std::string, Kept> kept_;
  std::mutex images_mu_;  // one image made at a time (they are cached)
};

}  // namespace locus::rpc
