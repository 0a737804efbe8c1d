#include "server/http_api.h"

#include <google/protobuf/util/json_util.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "common/base/image.h"
#include "common/base/log.h"
#include "common/base/png.h"
#include "common/farm/movie.h"
#include "server/dashboard_assets.h"

namespace locus::rpc {
namespace {
namespace fs = std::filesystem;
using Headers = std::vector<std::pair<std::string, std::string>>;

// Each Code as HTTP says it, and its name in the JSON error.
struct CodeWords {
  Code code;
  int http;
  const char* name;
};
constexpr CodeWords kCodes[] = {
    {Code::kOk, 200, "OK"},
    {Code::kInvalidArgument, 400, "INVALID_ARGUMENT"},
    {Code::kNotFound, 404, "NOT_FOUND"},
    {Code::kAlreadyExists, 409, "ALREADY_EXISTS"},
    {Code::kFailedPrecondition, 409, "FAILED_PRECONDITION"},
    {Code::kResourceExhausted, 429, "RESOURCE_EXHAUSTED"},
    {Code::kPermissionDenied, 403, "PERMISSION_DENIED"},
    {Code::kUnauthenticated, 401, "UNAUTHENTICATED"},
    {Code::kUnavailable, 503, "UNAVAILABLE"},
    {Code::kDeadlineExceeded, 504, "DEADLINE_EXCEEDED"},
    {Code::kCancelled, 499, "CANCELLED"},
    {Code::kAborted, 409, "ABORTED"},
    {Code::kInternal, 500, "INTERNAL"},
};

const CodeWords& words(Code code) {
  for (const CodeWords& w : kCodes) {
    if (w.code == code) return w;
  }
  return kCodes[std::size(kCodes) - 1];
}

// A JSON string (log.h's escaping, which also mends invalid UTF-8), with
// <, > and & as \u escapes so that no HTML can be read into it.
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : json_escape(s)) {
    if (c == '<') {
      out += "\\u003c";
    } else if (c == '>') {
      out += "\\u003e";
    } else if (c == '&') {
      out += "\\u0026";
    } else {
      out += c;
    }
  }
  return out + "\"";
}

HttpResponse error(const Status& s) {
  HttpResponse r;
  const CodeWords& w = words(s.code());
  r.status = w.http;
  r.body = std::string("{\"error\":{\"code\":\"") + w.name +
           "\",\"message\":" + json_string(s.message()) + "}}";
  if (s.code() == Code::kUnauthenticated) r.headers.emplace_back("WWW-Authenticate", "Bearer");
  return r;
}

HttpResponse error(int http, const std::string& code, const std::string& message) {
  HttpResponse r;
  r.status = http;
  r.body = "{\"error\":{\"code\":\"" + code + "\",\"message\":" + json_string(message) + "}}";
  return r;
}

HttpResponse json(const google::protobuf::Message& m) {
  google::protobuf::util::JsonPrintOptions o;
  o.always_print_primitive_fields = true;
  o.preserve_proto_field_names = true;
  HttpResponse r;
  if (!google::protobuf::util::MessageToJsonString(m, &r.body, o).ok()) {
    return error(Status(Code::kInternal, "cannot print the answer as JSON"));
  }
  return r;
}

// A handler's answer: its message as JSON, or its error.
HttpResponse answer(const Status& s, const google::protobuf::Message& m) {
  return s.ok() ? json(m) : error(s);
}

// The JSON body into a request message: unknown fields are an error that
// names them; an empty body is an empty message.
Status parse_body(const std::string& body, google::protobuf::Message* m) {
  if (body.empty()) return Status::Ok();
  google::protobuf::util::JsonParseOptions o;
  o.ignore_unknown_fields = false;
  const auto st = google::protobuf::util::JsonStringToMessage(body, m, o);
  if (!st.ok()) {
    return InvalidArgument("request body: " + std::string(st.message().data(), st.message().size()));
  }
  return Status::Ok();
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// %XX and '+' decoded; a malformed escape is kept as it is.
std::string decode(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hex_digit(s[i + 1]) >= 0 && hex_digit(s[i + 2]) >= 0) {
      out += static_cast<char>(hex_digit(s[i + 1]) * 16 + hex_digit(s[i + 2]));
      i += 2;
    } else {
      out += s[i] == '+' ? ' ' : s[i];
    }
  }
  return out;
}

std::map<std::string, std::string> parse_query(const std::string& q) {
  std::map<std::string, std::string> out;
  std::istringstream in(q);
  std::string pair;
  while (std::getline(in, pair, '&')) {
    const size_t eq = pair.find('=');
    out[decode(pair.substr(0, eq))] = eq == std::string::npos ? "" : decode(pair.substr(eq + 1));
  }
  return out;
}

std::vector<std::string> split_path(const std::string& path) {
  std::vector<std::string> parts;
  std::istringstream in(path);
  std::string p;
  while (std::getline(in, p, '/')) {
    if (!p.empty()) parts.push_back(p);
  }
  return parts;
}

// A whole decimal number in [lo, hi], or an error naming the parameter.
Result<int64_t> number(const std::string& text, const char* what, int64_t lo, int64_t hi) {
  if (text.empty() || text.size() > 19) return InvalidArgument(std::string(what) + ": not a number");
  int64_t v = 0;
  size_t i = text[0] == '-' ? 1 : 0;
  if (i == text.size()) return InvalidArgument(std::string(what) + ": not a number");
  for (; i < text.size(); ++i) {
    if (text[i] < '0' || text[i] > '9') {
      return InvalidArgument(std::string(what) + ": '" + text.substr(0, 40) + "' is not a number");
    }
    v = v * 10 + (text[i] - '0');
  }
  if (text[0] == '-') v = -v;
  if (v < lo || v > hi) {
    return InvalidArgument(std::string(what) + ": must be in [" + std::to_string(lo) + ", " +
                           std::to_string(hi) + "]");
  }
  return v;
}

// The file as a PNG response.
HttpResponse png_file(const std::string& path) {
  HttpResponse r;
  r.content_type = "image/png";
  r.file = path;
  r.headers.emplace_back("Cache-Control", "no-cache");
  return r;
}

// Each output pixel is the mean of a k x k block of input pixels (fewer at
// the right and bottom edges), k the smallest integer that fits the width.
Image box_downscale(const Image& in, int max_width) {
  const int k = std::max(1, (in.width + max_width - 1) / max_width);
  Image out((in.width + k - 1) / k, (in.height + k - 1) / k);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      double sum[3] = {0, 0, 0};
      int n = 0;
      for (int yy = y * k; yy < std::min(in.height, (y + 1) * k); ++yy) {
        for (int xx = x * k; xx < std::min(in.width, (x + 1) * k); ++xx) {
          const float* p = in.pixel(xx, yy);
          for (int c = 0; c < 3; ++c) sum[c] += p[c];
          ++n;
        }
      }
      float* o = out.pixel(x, y);
      for (int c = 0; c < 3; ++c) o[c] = static_cast<float>(sum[c] / n);
    }
  }
  return out;
}

// `cached` when it is newer than `source`; otherwise made by `make` and
// renamed into place.
Status refresh(const fs::path& source, const fs::path& cached,
               const std::function<Result<Image>(const Image&)>& make) {
  std::error_code ec;
  const auto src_time = fs::last_write_time(source, ec);
  if (ec) return NotFound(source.filename().string() + ": no such frame file");
  const auto cached_time = fs::last_write_time(cached, ec);
  if (!ec && cached_time >= src_time) return Status::Ok();
  auto frame = read_image(source.string());
  if (!frame.ok()) return frame.status();
  auto image = make(*frame);
  if (!image.ok()) return image.status();
  auto bytes = encode_png(*image, PngTag::kDisplay);
  if (!bytes.ok()) return bytes.status();
  fs::create_directories(cached.parent_path(), ec);
  const fs::path tmp = cached.string() + ".partial";
  if (Status s = write_file(tmp.string(), *bytes); !s.ok()) return s;
  fs::rename(tmp, cached, ec);
  if (ec) return Internal(cached.string() + ": " + ec.message());
  return Status::Ok();
}

}  // namespace

const Headers& HttpApi::security_headers() {
  static const Headers h = {
      {"Content-Security-Policy",
       "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
       "media-src 'self' blob:; connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"},
      {"X-Content-Type-Options", "nosniff"},
      {"X-Frame-Options", "DENY"},
      {"Referrer-Policy", "no-referrer"},
  };
  return h;
}

HttpApi::HttpApi(farm::Coordinator& coordinator, Handlers& handlers,
                 const farm::Authenticator& auth, HttpOptions options)
    : c_(coordinator), h_(handlers), auth_(auth), options_(options) {}

bool HttpApi::allow(const std::string& remote) {
  std::lock_guard lk(rate_mu_);
  const auto now = Clock::now();
  if (buckets_.size() > 10000) buckets_.clear();  // bounded, whoever knocks
  auto [it, fresh] = buckets_.try_emplace(remote, Bucket{options_.burst, now});
  Bucket& b = it->second;
  if (!fresh) {
    b.tokens = std::min(options_.burst,
                        b.tokens + options_.rate * std::chrono::duration<double>(now - b.at).count());
    b.at = now;
  }
  if (b.tokens < 1) return false;
  b.tokens -= 1;
  return true;
}

HttpResponse HttpApi::reused(const std::string& key, const std::function<HttpResponse()>& make) {
  const auto now = Clock::now();
  {
    std::lock_guard lk(reuse_mu_);
    auto it = kept_.find(key);
    if (it != kept_.end() && now - it->second.at < options_.reuse) return it->second.response;
  }
  HttpResponse r = make();
  if (r.status == 200 && options_.reuse.count() > 0) {
    std::lock_guard lk(reuse_mu_);
    if (kept_.size() > 1000) kept_.clear();  // bounded: users x jobs being watched
    kept_[key] = Kept{r, now};
  }
  return r;
}

HttpResponse HttpApi::handle(const HttpRequest& req) {
  HttpResponse r;
  try {
    if (!allow(req.remote)) {
      r = error(429, "RESOURCE_EXHAUSTED", "too many requests from " + req.remote.substr(0, 64) +
                                               "; slow down");
    } else if (req.path.size() > options_.max_path || req.query.size() > options_.max_path) {
      r = error(414, "INVALID_ARGUMENT", "the request's path or query is too long");
    } else if (req.body.size() > options_.max_body) {
      r = error(413, "INVALID_ARGUMENT",
                "the request body is over " + std::to_string(options_.max_body) + " bytes");
    } else {
      const std::vector<std::string> parts = split_path(req.path);
      if (parts.size() < 2 || parts[0] != "api" || parts[1] != "v1") {
        // The pages: static, and the same for everyone (no data in them).
        const DashboardAsset* asset = dashboard_asset(parts.empty() ? "index.html" : parts[0]);
        if (parts.size() > 1 || !asset) {
          r = error(404, "NOT_FOUND", "no such page; the dashboard is at /");
        } else if (req.method != "GET" && req.method != "HEAD") {
          r = error(405, "INVALID_ARGUMENT", "pages are read with GET");
        } else {
          r.content_type = asset->content_type;
          r.body.assign(asset->data, asset->size);
          r.headers.emplace_back("Cache-Control", "no-cache");
        }
      } else {
        // The API: a client token (or an admin's) on every call, in the
        // Authorization header only. No cookie is ever read, so another
        // site's page cannot act with the user's rights (no CSRF); POSTs
        // must also say JSON (a cross-site form cannot, without a CORS
        // preflight this server never grants) and come from this origin.
        auto caller = auth_.identify(farm::Role::kClient, req.authorization, false, "the HTTP API");
        if (!caller.ok()) {
          spdlog::warn("http: refused {} {} from {}: {}", req.method, req.path.substr(0, 64),
                       req.remote.substr(0, 64), caller.status().message());
          r = error(caller.status());
        } else if (req.method == "POST" &&
                   req.content_type.rfind("application/json", 0) != 0) {
          r = error(415, "INVALID_ARGUMENT", "POST bodies are JSON: Content-Type: application/json");
        } else if (req.method == "POST" && !req.origin.empty() &&
                   req.origin != "http://" + req.host && req.origin != "https://" + req.host) {
          r = error(403, "PERMISSION_DENIED", "a request from another origin is refused");
        } else {
          r = route(req, std::vector<std::string>(parts.begin() + 2, parts.end()), *caller);
          if (req.method == "POST" && r.status == 200) {
            // An action changed the farm: what was kept is stale for
            // everyone (a script reading the job right after sees it).
            std::lock_guard lk(reuse_mu_);
            kept_.clear();
          }
          if (r.status == 403) {
            spdlog::warn("http: {} {} by {}: permission denied", req.method,
                         req.path.substr(0, 64), caller->user);
          }
        }
      }
      if (r.file.empty() && r.content_type == "application/json")
        r.headers.emplace_back("Cache-Control", "no-store");
    }
  } catch (const std::exception& e) {
    spdlog::error("http: {} {}: {}", req.method, req.path.substr(0, 64), e.what());
    r = error(Status(Code::kInternal, e.what()));
  }
  for (const auto& h : security_headers()) r.headers.push_back(h);
  return r;
}

HttpResponse HttpApi::route(const HttpRequest& req, const std::vector<std::string>& p,
                            const farm::Caller& caller) {
  const bool get = req.method == "GET" || req.method == "HEAD";
  const bool post = req.method == "POST";
  const auto q = parse_query(req.query);
  const auto query_int = [&](const char* key, int64_t lo, int64_t hi,
                             int64_t fallback) -> Result<int64_t> {
    auto it = q.find(key);
    if (it == q.end()) return fallback;
    return number(it->second, key, lo, hi);
  };
  const auto not_allowed = [&] {
    return error(405, "INVALID_ARGUMENT",
                 req.method.substr(0, 16) + " is not allowed on " + req.path.substr(0, 200));
  };
  if (p.empty()) return error(404, "NOT_FOUND", "no such API route; docs/http-api.md lists them");

  // What one user may see is the same for all of that user's watchers.
  const std::string who = caller.user + (caller.admin ? "|admin" : "|");
  // GET farm?since=V: the snapshot, reused for options_.reuse; "unchanged"
  // when the caller's cursor is the snapshot's version.
  if (p.size() == 1 && p[0] == "farm") {
    if (!get) return not_allowed();
    auto since = query_int("since", 0, INT64_MAX, 0);
    if (!since.ok()) return error(since.status());
    const auto snapshot = [&] {
      v1::FarmSnapshot out;
      return answer(h_.GetFarm(v1::GetFarmRequest(), caller, &out), out);
    };
    HttpResponse r = reused("farm|" + who, snapshot);
    if (r.status == 200 && *since > 0) {
      const std::string mark = "\"version\":\"" + std::to_string(*since) + "\",";
      if (r.body.rfind("{" + mark, 0) == 0) {
        r.body = "{" + mark + "\"unchanged\":true,\"jobs\":[],\"workers\":[]}";
      }
    }
    return r;
  }
  if (p.size() == 1 && p[0] == "jobs") {
    if (!get) return not_allowed();
    v1::ListJobsResponse out;
    return answer(h_.ListJobs(v1::ListJobsRequest(), caller, &out), out);
  }
  if (p.size() == 1 && p[0] == "workers") {
    if (!get) return not_allowed();
    v1::ListWorkersResponse out;
    return answer(h_.ListWorkers(v1::ListWorkersRequest(), &out), out);
  }
  if (p[0] == "workers" && p.size() == 2) {
    if (!get) return not_allowed();
    v1::GetWorkerRequest r;
    r.set_worker(p[1]);
    v1::WorkerStatus out;
    return answer(h_.GetWorker(r, caller, &out), out);
  }
  if (p[0] == "workers" && p.size() == 3) {
    if (!post) return not_allowed();
    v1::WorkerActionRequest r;
    r.set_worker(p[1]);
    v1::WorkerActionResponse out;
    if (p[2] == "drain") return answer(h_.DrainWorker(r, caller, &out), out);
    if (p[2] == "disable") return answer(h_.DisableWorker(r, caller, &out), out);
    if (p[2] == "enable") return answer(h_.EnableWorker(r, caller, &out), out);
    return error(404, "NOT_FOUND", "workers: the actions are drain, disable and enable");
  }
  if (p[0] != "jobs") return error(404, "NOT_FOUND", "no such API route; docs/http-api.md lists them");
  const std::string& job = p[1];
  if (p.size() == 2) {
    if (!get) return not_allowed();
    return reused("job|" + job + "|" + who, [&] {
      v1::GetJobRequest r;
      r.set_job_id(job);
      v1::JobStatus out;
      return answer(h_.GetJob(r, caller, &out), out);
    });
  }
  const std::string& what = p[2];
  if (p.size() == 3 && (what == "events" || what == "logs")) {
    if (!get) return not_allowed();
    auto after = query_int("after", 0, INT64_MAX, 0);
    auto limit = query_int("limit", 1, farm::kMaxEventsPerCall, 1000);
    if (!after.ok()) return error(after.status());
    if (!limit.ok()) return error(limit.status());
    if (what == "events") {
      v1::ListEventsRequest r;
      r.set_job_id(job);
      r.set_after_seq(*after);
      r.set_limit(static_cast<int32_t>(*limit));
      v1::ListEventsResponse out;
      return answer(h_.ListEvents(r, caller, &out), out);
    }
    v1::ListLogsRequest r;
    r.set_job_id(job);
    r.set_after_seq(*after);
    r.set_limit(static_cast<int32_t>(*limit));
    auto frame = query_int("frame", -1, INT32_MAX, -1);
    auto band = query_int("band", -1, INT32_MAX, -1);
    if (!frame.ok()) return error(frame.status());
    if (!band.ok()) return error(band.status());
    if (*frame >= 0) r.set_frame(static_cast<int32_t>(*frame));
    if (*band >= 0) r.set_band(static_cast<int32_t>(*band));
    v1::ListLogsResponse out;
    return answer(h_.ListLogs(r, caller, &out), out);
  }
  if (what == "frames" && p.size() >= 4) {
    if (!get) return not_allowed();
    if (p.size() > 4) return image(p, caller);
    auto frame = number(p[3], "frame", INT32_MIN, INT32_MAX);
    if (!frame.ok()) return error(frame.status());
    v1::GetFrameRequest r;
    r.set_job_id(job);
    r.set_frame(static_cast<int32_t>(*frame));
    v1::FrameStatus out;
    return answer(h_.GetFrame(r, caller, &out), out);
  }
  if (p.size() != 3) return error(404, "NOT_FOUND", "no such API route; docs/http-api.md lists them");
  // The actions: POST with a JSON body (may be empty for most).
  if (!post) return not_allowed();
  v1::JobActionResponse out;
  if (what == "pause" || what == "resume" || what == "retry") {
    v1::JobActionRequest r;
    if (Status s = parse_body(req.body, &r); !s.ok()) return error(s);
    r.set_job_id(job);
    const Status s = what == "pause"    ? h_.PauseJob(r, caller, &out)
                     : what == "resume" ? h_.ResumeJob(r, caller, &out)
                                        : h_.RetryJob(r, caller, &out);
    return answer(s, out);
  }
  if (what == "cancel") {
    v1::CancelJobRequest r;
    if (Status s = parse_body(req.body, &r); !s.ok()) return error(s);
    r.set_job_id(job);
    v1::CancelJobResponse c;
    return answer(h_.CancelJob(r, caller, &c), c);
  }
  if (what == "priority") {
    v1::SetPriorityRequest r;
    if (Status s = parse_body(req.body, &r); !s.ok()) return error(s);
    r.set_job_id(job);
    return answer(h_.SetPriority(r, caller, &out), out);
  }
  if (what == "requeue") {
    v1::RequeueJobRequest r;
    if (Status s = parse_body(req.body, &r); !s.ok()) return error(s);
    r.set_job_id(job);
    return answer(h_.RequeueJob(r, caller, &out), out);
  }
  if (what == "delete") {
    v1::DeleteJobRequest r;
    if (Status s = parse_body(req.body, &r); !s.ok()) return error(s);
    r.set_job_id(job);
    return answer(h_.DeleteJob(r, caller, &out), out);
  }
  return error(404, "NOT_FOUND",
               "jobs: the actions are pause, resume, cancel, retry, requeue, priority and delete");
}

HttpResponse HttpApi::png_now(const Image& image) {
  std::lock_guard lk(images_mu_);
  auto bytes = encode_png(image, PngTag::kDisplay);
  if (!bytes.ok()) return error(bytes.status());
  HttpResponse r;
  r.content_type = "image/png";
  r.body = std::move(*bytes);
  r.headers.emplace_back("Cache-Control", "no-cache");
  return r;
}

// GET jobs/J/frames/F/image      the written frame as PNG (1:1)
// GET jobs/J/frames/F/thumbnail  a box-filtered downscale, at most
//                                thumbnail_width wide
// GET jobs/J/frames/F/cost-map   the frame's cost map as PNG (a job submitted
//                                with a cost map; docs/cost-map.md): the
//                                written file's, or for a frame in progress
//                                the bands accepted so far (header
//                                X-Locus-Bands-In: how many)
// GET jobs/J/frames/F/bands/B/image  an accepted band of a frame in progress
// GET jobs/J/frames/1/movie      a movie job's movie (MP4, WebM or GIF)
HttpResponse HttpApi::image(const std::vector<std::string>& p, const farm::Caller& caller) {
  const std::string& job = p[1];
  auto frame = number(p[3], "frame", INT32_MIN, INT32_MAX);
  if (!frame.ok()) return error(frame.status());
  const int f = static_cast<int>(*frame);
  if (p.size() == 7 && p[4] == "bands" && p[6] == "image") {
    auto band = number(p[5], "band", 0, INT32_MAX);
    if (!band.ok()) return error(band.status());
    auto pixels = c_.band_image(job, f, static_cast<int>(*band), caller);
    if (!pixels.ok()) return error(pixels.status());
    return png_now(*pixels);
  }
  if (p.size() != 5 ||
      (p[4] != "image" && p[4] != "thumbnail" && p[4] != "movie" && p[4] != "cost-map")) {
    return error(404, "NOT_FOUND",
                 "frames: the images are image, thumbnail, cost-map and bands/B/image; a movie "
                 "job's file is frames/1/movie");
  }
  if (p[4] == "cost-map") {
    auto path = c_.frame_file(job, f, caller, /*cost_map=*/true);
    if (!path.ok() && path.status().code() == Code::kNotFound) {
      // A frame in progress: the bands accepted so far, drawn now.
      int in = 0;
      auto partial = c_.partial_cost_map(job, f, &in, caller);
      if (!partial.ok()) return error(partial.status());
      HttpResponse r = png_now(*partial);
      r.headers.emplace_back("X-Locus-Bands-In", std::to_string(in));
      return r;
    }
    if (!path.ok()) return error(path.status());
    // A PNG for the browser whatever the cost map's format (the same values).
    const fs::path png =
        fs::path(c_.job_dir(job)) / ".dashboard" / ("cost-" + std::to_string(f) + ".png");
    std::lock_guard lk(images_mu_);
    if (Status s = refresh(*path, png, [](const Image& i) -> Result<Image> { return i; }); !s.ok())
      return error(s);
    return png_file(png.string());
  }
  auto path = c_.frame_file(job, f, caller);
  if (!path.ok()) return error(path.status());
  const fs::path source = *path;
  // A movie job's one output (docs/farm.md "Movies"), served as it is.
  const auto movie = farm::movie_format(source.string(), "movie");
  if (p[4] == "movie" || movie.ok()) {
    if (p[4] != "movie" || !movie.ok()) {
      return error(404, "NOT_FOUND",
                   movie.ok() ? "job " + job + " is a movie job: GET jobs/" + job + "/frames/1/movie"
                              : "job " + job + " is not a movie job: its frames are frames/F/image");
    }
    HttpResponse r;
    r.content_type = *movie == farm::MovieFormat::kMp4    ? "video/mp4"
                     : *movie == farm::MovieFormat::kWebm ? "video/webm"
                                                          : "image/gif";
    r.file = source.string();
    r.headers.emplace_back("Cache-Control", "no-cache");
    return r;
  }
  const fs::path cache = fs::path(c_.job_dir(job)) / ".dashboard";
  std::lock_guard lk(images_mu_);
  if (p[4] == "image") {
    // A copy tagged for display (the frame's PNG says "linear", which a
    // browser would brighten); the same pixel values; EXR and TIFF frames
    // clamped like 8-bit output.
    const fs::path png = cache / ("frame-" + std::to_string(f) + ".png");
    if (Status s = refresh(source, png, [](const Image& i) -> Result<Image> { return i; });
        !s.ok()) {
      return error(s);
    }
    return png_file(png.string());
  }
  const int width = options_.thumbnail_width;
  const fs::path thumb = cache / ("thumb-" + std::to_string(f) + ".png");
  if (Status s = refresh(source, thumb,
                         [width](const Image& i) -> Result<Image> { return box_downscale(i, width); });
      !s.ok()) {
    return error(s);
  }
  return png_file(thumb.string());
}

}  // namespace locus::rpc
