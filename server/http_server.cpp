#include "server/http_server.h"

#include <civetweb.h>
#include <spdlog/spdlog.h>
#include <dlfcn.h>
#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <vector>

namespace locus::rpc {
namespace {
namespace fs = std::filesystem;

const char* reason(int status) {
  switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 413: return "Payload Too Large";
    case 414: return "URI Too Long";
    case 415: return "Unsupported Media Type";
    case 429: return "Too Many Requests";
    case 503: return "Service Unavailable";
    default: return status < 500 ? "Error" : "Server Error";
  }
}

std::string header(const mg_request_info* ri, const char* name) {
  for (int i = 0; i < ri->num_headers; ++i) {
    if (strcasecmp(ri->http_headers[i].name, name) == 0 && ri->http_headers[i].value)
      return ri->http_headers[i].value;
  }
  return "";
}

Result<std::string> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(fs::path(path).filename().string() + ": cannot be read");
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// civetweb's own messages go to our log (never the request's token: it
// logs no headers).
int log_message(const ::mg_connection*, const char* message) {
  spdlog::debug("http: {}", message);
  return 1;
}

}  // namespace

Result<std::unique_ptr<HttpServer>> HttpServer::start(const HttpServerOptions& o, HttpApi& api) {
  static std::once_flag init;
  std::call_once(init, [] { mg_init_library(MG_FEATURES_TLS); });
  const size_t colon = o.address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == o.address.size()) {
    return InvalidArgument("--http " + o.address + ": expected HOST:PORT");
  }
  std::unique_ptr<HttpServer> s(new HttpServer(api));
  s->max_body_ = api.options().max_body;
  std::string ports = o.address;
  if (!o.tls_cert.empty() || !o.tls_key.empty()) {
    // civetweb reads the key and the chain from one PEM file: joined here,
    // readable by this user only.
    auto cert = read_file(o.tls_cert);
    auto key = read_file(o.tls_key);
    if (!cert.ok() || !key.ok()) {
      return InvalidArgument("--http with TLS: cannot read --tls-cert or --tls-key");
    }
    std::error_code ec;
    fs::create_directories(o.scratch_dir, ec);
    s->pem_ = (fs::path(o.scratch_dir) / "http-tls.pem").string();
    const mode_t old = ::umask(077);
    {
      std::ofstream out(s->pem_, std::ios::binary | std::ios::trunc);
      out << *key << "\n" << *cert;
    }
    ::umask(old);
    ::chmod(s->pem_.c_str(), 0600);
    // civetweb loads OpenSSL itself, by its unversioned names: say so
    // plainly when they are missing instead of failing to serve.
    for (const char* lib : {"libssl.so", "libcrypto.so"}) {
      void* h = ::dlopen(lib, RTLD_LAZY);
      if (!h) {
        return FailedPrecondition(std::string("--http with TLS: civetweb needs ") + lib +
                                  ", which this host lacks (install libssl-dev, or link it to "
                                  "the versioned library, e.g. libssl.so.3)");
      }
      ::dlclose(h);
    }
    ports += "s";
    s->tls_ = true;
  }
  const std::string threads = std::to_string(std::max(1, o.threads));
  std::vector<const char*> options = {"listening_ports", ports.c_str(), "num_threads",
                                      threads.c_str(), "enable_keep_alive", "no",
                                      "request_timeout_ms", "10000", "max_request_size",
                                      "16384"};
  if (s->tls_) {
    options.insert(options.end(), {"ssl_certificate", s->pem_.c_str(), "ssl_protocol_version",
                                   "4"});
  }
  options.push_back(nullptr);
  mg_callbacks callbacks{};
  callbacks.log_message = log_message;
  s->ctx_ = mg_start(&callbacks, nullptr, options.data());
  if (!s->ctx_) {
    return Status(Code::kUnavailable, "--http " + o.address +
                                          ": cannot serve there (in use, not an address of this "
                                          "host, or a bad certificate)");
  }
  mg_set_request_handler(s->ctx_, "/", &HttpServer::serve, s.get());
  mg_server_port port{};
  if (mg_get_server_ports(s->ctx_, 1, &port) < 1) {
    return Status(Code::kUnavailable, "--http " + o.address + ": no port was bound");
  }
  s->port_ = port.port;
  return s;
}

HttpServer::~HttpServer() {
  if (ctx_) mg_stop(ctx_);
  if (!pem_.empty()) {
    std::error_code ec;
    fs::remove(pem_, ec);
  }
}

int HttpServer::serve(mg_connection* conn, void* self) {
  auto* server = static_cast<HttpServer*>(self);
  const mg_request_info* ri = mg_get_request_info(conn);
  HttpRequest req;
  req.method = ri->request_method ? ri->request_method : "";
  req.path = ri->local_uri_raw ? ri->local_uri_raw : "";
  req.query = ri->query_string ? ri->query_string : "";
  req.authorization = header(ri, "Authorization");
  req.content_type = header(ri, "Content-Type");
  req.origin = header(ri, "Origin");
  req.host = header(ri, "Host");
  req.remote = ri->remote_addr;
  HttpResponse resp;
  if (ri->content_length > static_cast<long long>(server->max_body_)) {
    req.body.assign(server->max_body_ + 1, ' ');  // refused by size, unread
  } else {
    char buf[8192];
    for (;;) {
      const int n = mg_read(conn, buf, sizeof buf);
      if (n <= 0) break;
      req.body.append(buf, static_cast<size_t>(n));
      if (req.body.size() > server->max_body_) break;
    }
  }
  resp = server->api_.handle(req);
  if (!resp.file.empty()) {
    auto bytes = read_file(resp.file);
    if (bytes.ok()) {
      resp.body = std::move(*bytes);
    } else {
      resp.status = 404;
      resp.content_type = "application/json";
      resp.body = R"({"error":{"code":"NOT_FOUND","message":"the image went away; reload"}})";
    }
  }
  std::string head = "HTTP/1.1 " + std::to_string(resp.status) + " " + reason(resp.status) +
                     "\r\nContent-Type: " + resp.content_type +
                     "\r\nContent-Length: " + std::to_string(resp.body.size()) +
                     "\r\nConnection: close\r\n";
  for (const auto& [name, value] : resp.headers) head += name + ": " + value + "\r\n";
  head += "\r\n";
  mg_write(conn, head.data(), head.size());
  if (req.method != "HEAD") mg_write(conn, resp.body.data(), resp.body.size());
  return resp.status;  // civetweb: a status code means "handled"
}

}  // namespace locus::rpc
