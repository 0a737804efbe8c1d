// The HTTP server of `locus-coordinator --http ADDR`: civetweb (Debian's,
// the library prometheus-cpp's exposer is built on) parses HTTP and holds
// the connections; each request is copied into an HttpRequest and answered
// by HttpApi (server/http_api.h), which knows nothing of sockets. TLS with
// the gRPC port's certificate and key when those are given.
#pragma once

#include <memory>
#include <string>

#include "common/base/status.h"
#include "server/http_api.h"

struct mg_context;
struct mg_connection;

namespace locus::rpc {

struct HttpServerOptions {
  std::string address;   // HOST:PORT; port 0: any free port
  std::string tls_cert;  // PEM files; both empty: plaintext
  std::string tls_key;
  std::string scratch_dir;  // where the key and certificate are joined for civetweb
  int threads = 8;          // connections served at once; keep-alive is off
};

class HttpServer {
 public:
  // Unavailable when the address cannot be bound; InvalidArgument for a
  // malformed address or unreadable TLS files.
  static Result<std::unique_ptr<HttpServer>> start(const HttpServerOptions& options,
                                                   HttpApi& api);
  ~HttpServer();  // stops: running requests finish first
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const { return port_; }
  bool tls() const { return tls_; }

 private:
  HttpServer(HttpApi& api) : api_(api) {}
  static int serve(::mg_connection* conn, void* self);
  HttpApi& api_;
  mg_context* ctx_ = nullptr;
  int port_ = 0;
  bool tls_ = false;
  size_t max_body_ = 0;
  std::string pem_;  // the joined key and certificate, removed at stop
};

}  // namespace locus::rpc
