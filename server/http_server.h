// The HTTP server of `locus-coordinator --http ADDR`: cpp-httplib (Debian's
// libcpp-httplib-dev, header-only, on the system's OpenSSL) parses HTTP and
// holds the connections; each request is copied into an HttpRequest and
// answered by HttpApi (server/http_api.h), which knows nothing of sockets.
// TLS with the gRPC port's certificate and key when those are given.
#pragma once

#include <memory>
#include <string>
#include <thread>

#include "common/base/status.h"
#include "server/http_api.h"

namespace httplib {
class Server;
}

namespace locus::rpc {

struct HttpServerOptions {
  std::string address;   // HOST:PORT; port 0: any free port
  std::string tls_cert;  // PEM files; both empty: plaintext
  std::string tls_key;
  int threads = 8;  // requests served at once; keep-alive is off
};

class HttpServer {
 public:
  // Unavailable when the address cannot be bound; InvalidArgument for a
  // malformed address or unusable TLS files.
  static Result<std::unique_ptr<HttpServer>> start(const HttpServerOptions& options,
                                                   HttpApi& api);
  ~HttpServer();  // stops: running requests finish first
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const { return port_; }
  bool tls() const { return tls_; }

 private:
  explicit HttpServer(HttpApi& api);
  HttpApi& api_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  int port_ = 0;
  bool tls_ = false;
};

}  // namespace locus::rpc
