// CPPHTTPLIB_OPENSSL_SUPPORT and the others come from cpp-httplib's
// pkg-config flags (server/CMakeLists.txt), as its library was built.
#pragma GCC diagnostic push  // OpenSSL 3 deprecates calls the header makes
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <httplib.h>
#pragma GCC diagnostic pop

#include "server/http_server.h"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <iterator>

namespace locus::rpc {
namespace {

Result<std::string> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFound(std::filesystem::path(path).filename().string() + ": cannot be read");
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void answer(HttpApi& api, const httplib::Request& in, httplib::Response& out) {
  HttpRequest req;
  req.method = in.method;
  req.path = in.path;  // decoded by httplib
  const size_t q = in.target.find('?');
  req.query = q == std::string::npos ? "" : in.target.substr(q + 1);
  req.authorization = in.get_header_value("Authorization");
  req.content_type = in.get_header_value("Content-Type");
  req.origin = in.get_header_value("Origin");
  req.host = in.get_header_value("Host");
  req.body = in.body;
  req.remote = in.remote_addr;
  HttpResponse r = api.handle(req);
  if (!r.file.empty()) {
    auto bytes = read_file(r.file);
    if (bytes.ok()) {
      r.body = std::move(*bytes);
    } else {
      r.status = 404;
      r.content_type = "application/json";
      r.body = R"({"error":{"code":"NOT_FOUND","message":"the image went away; reload"}})";
    }
  }
  out.status = r.status;
  for (const auto& [name, value] : r.headers) out.set_header(name, value);
  out.set_content(std::move(r.body), r.content_type.c_str());
}

}  // namespace

Result<std::unique_ptr<HttpServer>> HttpServer::start(const HttpServerOptions& o, HttpApi& api) {
  const size_t colon = o.address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == o.address.size()) {
    return InvalidArgument("--http " + o.address + ": expected HOST:PORT");
  }
  int wanted = 0;
  try {
    wanted = std::stoi(o.address.substr(colon + 1));
  } catch (const std::exception&) {
    return InvalidArgument("--http " + o.address + ": the port is not a number");
  }
  std::string host = o.address.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  std::unique_ptr<HttpServer> s(new HttpServer(api));
  if (!o.tls_cert.empty() || !o.tls_key.empty()) {
    auto tls = std::make_unique<httplib::SSLServer>(o.tls_cert.c_str(), o.tls_key.c_str());
    if (!tls->is_valid()) {
      return InvalidArgument("--http with TLS: cannot use --tls-cert " + o.tls_cert +
                             " and --tls-key " + o.tls_key);
    }
    s->server_ = std::move(tls);
    s->tls_ = true;
  } else {
    s->server_ = std::make_unique<httplib::Server>();
  }
  httplib::Server& server = *s->server_;
  const int threads = std::max(1, o.threads);
  server.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  server.set_keep_alive_max_count(1);  // a poll does not hold a thread between polls
  server.set_read_timeout(10, 0);
  server.set_write_timeout(10, 0);
  server.set_payload_max_length(api.options().max_body);
  const auto handler = [&api](const httplib::Request& in, httplib::Response& out) {
    answer(api, in, out);
  };
  for (auto route : {&httplib::Server::Get, &httplib::Server::Post, &httplib::Server::Put,
                     &httplib::Server::Delete, &httplib::Server::Patch, &httplib::Server::Options}) {
    (server.*route)(".*", handler);
  }
  server.set_exception_handler([](const httplib::Request& in, httplib::Response& out,
                                  std::exception_ptr) {
    spdlog::error("http: {} {}: an exception", in.method, in.path.substr(0, 64));
    out.status = 500;
    out.set_content(R"({"error":{"code":"INTERNAL","message":"internal error"}})",
                    "application/json");
  });
  // httplib's own refusals (a malformed request, one too large) get the
  // security headers too.
  server.set_error_handler([](const httplib::Request&, httplib::Response& out) {
    for (const auto& [name, value] : HttpApi::security_headers()) out.set_header(name, value);
  });
  s->port_ = wanted == 0 ? server.bind_to_any_port(host) : (server.bind_to_port(host, wanted)
                                                                 ? wanted
                                                                 : -1);
  if (s->port_ <= 0) {
    return Status(Code::kUnavailable,
                  "--http " + o.address + ": cannot serve there (in use, or not an address of "
                  "this host)");
  }
  s->thread_ = std::thread([srv = s->server_.get()] { srv->listen_after_bind(); });
  return s;
}

HttpServer::HttpServer(HttpApi& api) : api_(api) {}

HttpServer::~HttpServer() {
  if (server_) server_->stop();
  if (thread_.joinable()) thread_.join();
}

}  // namespace locus::rpc
