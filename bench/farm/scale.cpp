// locus-farm-scale: the coordinator under many workers (issue #25; run by
// bench/farm/scale.sh, and small by tests/farm_scale/run.sh in CTest).
//
// N simulated workers live in this process. Each is a real gRPC client of
// the real coordinator with a connection of its own (gRPC's callback API,
// so that a thousand of them need no thousand threads here): it registers,
// long-polls GetTask, fetches the scene once, heartbeats while it holds a
// band and returns the band after a delay (0: the dispatch ceiling; or
// drawn from a log-normal distribution like real band times) with the
// pixels a worker would send. The frame is rendered once, before the
// clock starts, through the worker's own BandRenderer; each lease gets its
// rows of it, so the harness does not render while it measures.
//
// Some workers misbehave on purpose: --die workers drop their connection
// after their first lease (a killed host), --stall workers keep it and go
// silent (a hung host), --late workers return every band after its lease
// has lapsed without heartbeating (refused, the band leased again).
//
// Prints "key value" lines: bands/s, dispatch and completion latency
// percentiles (as the workers see them), the coordinator's CPU per band
// (/proc/PID/stat), its RSS and open file descriptors, the store's size;
// then checks what must hold whatever the speed: every job succeeded, every
// band accepted exactly once (the store's `bands.completions`), every frame
// identical to the reference. Exit 0 only if all of that holds.
#include <dirent.h>
#include <grpcpp/grpcpp.h>
#include <sqlite3.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <queue>
#include <random>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "client/farm_client.h"
#include "common/base/image.h"
#include "common/farm/band_codec.h"
#include "common/scene/scene_io.h"
#include "proto/locus.grpc.pb.h"
#include "proto/wire/rpc.h"
#include "worker/band_renderer.h"

namespace {

namespace fs = std::filesystem;
namespace v1 = locus::v1;
using Clock = std::chrono::steady_clock;
using Ms = std::chrono::milliseconds;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// ---------------------------------------------------------------- the process

// This process's CPU (user + system), all threads.
double own_cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
}

struct ProcessSample {
  double cpu_seconds = 0;  // user + system
  long rss_kib = 0;
  long hwm_kib = 0;
  int fds = 0;
};

ProcessSample sample(int pid) {
  ProcessSample s;
  if (pid <= 0) return s;
  const std::string dir = "/proc/" + std::to_string(pid);
  {
    std::ifstream f(dir + "/stat");
    std::string line;
    std::getline(f, line);
    // Fields after the command's closing parenthesis; utime and stime are
    // the 14th and 15th of the line, the 12th and 13th after it.
    const size_t close = line.rfind(')');
    if (close != std::string::npos) {
      std::istringstream rest(line.substr(close + 2));
      std::string field;
      long utime = 0, stime = 0;
      for (int i = 1; i <= 13 && rest >> field; ++i) {
        if (i == 12) utime = std::stol(field);
        if (i == 13) stime = std::stol(field);
      }
      s.cpu_seconds =
          static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
    }
  }
  std::ifstream f(dir + "/status");
  std::string key;
  while (f >> key) {
    if (key == "VmRSS:") f >> s.rss_kib;
    if (key == "VmHWM:") f >> s.hwm_kib;
  }
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir + "/fd", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    ++s.fds;
  }
  return s;
}

uintmax_t tree_bytes(const std::string& dir) {
  uintmax_t n = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file(ec)) n += it->file_size(ec);
  }
  return n;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

// ---------------------------------------------------------------- timers

// One thread running functions at their time (delays, retries, heartbeats).
class Timers {
 public:
  Timers() : thread_([this] { run(); }) {}
  ~Timers() {
    {
      std::lock_guard lk(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  void at(Clock::time_point when, std::function<void()> fn) {
    {
      std::lock_guard lk(mu_);
      queue_.push({when, seq_++, std::move(fn)});
    }
    cv_.notify_all();
  }

 private:
  struct Entry {
    Clock::time_point when;
    uint64_t seq;
    std::function<void()> fn;
    bool operator>(const Entry& o) const { return when != o.when ? when > o.when : seq > o.seq; }
  };
  void run() {
    std::unique_lock lk(mu_);
    while (!stop_) {
      if (queue_.empty()) {
        cv_.wait(lk);
        continue;
      }
      if (queue_.top().when > Clock::now()) {
        cv_.wait_until(lk, queue_.top().when);
        continue;
      }
      std::function<void()> fn = queue_.top().fn;
      queue_.pop();
      lk.unlock();
      fn();
      lk.lock();
    }
  }
  std::mutex mu_;
  std::condition_variable cv_;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue_;
  uint64_t seq_ = 0;
  bool stop_ = false;
  std::thread thread_;
};

// ---------------------------------------------------------------- the workers

enum class Behaviour { kNormal, kDie, kStall, kLate };

struct Shared {
  std::string address;
  v1::Scene scene;           // what GetScene would return (fetched once per worker all the same)
  std::vector<float> frame;  // the reference frame, linear RGB
  int width = 0;
  Timers* timers = nullptr;
  double delay_ms = 0;
  double delay_sigma = 0;   // log-normal spread of the delay; 0: fixed
  bool want_next = true;    // CompleteBandRequest.want_next (--no-next: GetTask for each band)
  bool png_deflate = true;  // RegisterRequest.encodings (--no-png-deflate: rgb8+zstd)
  int batch = 1;            // bands per call (GetTaskRequest.max_bands, CompleteBandRequest.more)
  int revive_ms = 0;        // a dying worker comes back after this long (0: never)
  bool outage_ok = false;   // the coordinator restarts during the run (a soak)
  std::atomic<bool> stopping{false};

  std::mutex mu;
  std::vector<double> dispatch_ms;    // GetTask sent to a band in hand
  std::vector<double> completion_ms;  // CompleteBand sent to its answer
  std::map<std::tuple<int, int, int>, std::shared_ptr<const std::string>>
      payloads;  // by rows, encoding
  int64_t accepted = 0, refused = 0, errors = 0, scene_fetches = 0, heartbeats = 0,
          registrations = 0;
  int64_t get_tasks = 0;       // GetTask calls
  int64_t outage_errors = 0;   // calls failed while the coordinator was away (--outage-ok)
  int64_t revived = 0;         // dead workers come back (--revive-ms)
  int64_t with_answer = 0;     // bands leased with a CompleteBand's answer
  int64_t complete_calls = 0;  // CompleteBand calls (several results each with --batch)
  Clock::time_point first_accept{}, last_accept{};

  // The CompleteBandRequest's pixels for rows [y0, y1), in the encoding
  // the band was leased with (BandTask.encoding), as locus-worker sends
  // them (worker/band_renderer.cpp); serialized once.
  std::shared_ptr<const std::string> payload(const v1::BandTask& task) {
    const int y0 = task.y0(), y1 = task.y1();
    const auto encoding = static_cast<locus::farm::BandEncoding>(task.encoding());
    std::lock_guard lk(mu);
    auto& p = payloads[{y0, y1, static_cast<int>(encoding)}];
    if (!p) {
      locus::farm::BandOutput out;
      const size_t begin = static_cast<size_t>(y0) * width * 3;
      const size_t end = static_cast<size_t>(y1) * width * 3;
      out.rgb.assign(frame.begin() + static_cast<std::ptrdiff_t>(begin),
                     frame.begin() + static_cast<std::ptrdiff_t>(end));
      if (encoding != locus::farm::BandEncoding::kFloat32) {
        auto encoded = locus::farm::encode_band(encoding, width, y1 - y0, out.rgb);
        if (!encoded.ok()) {
          std::fprintf(stderr, "encode: %s\n", encoded.status().message().c_str());
          std::_Exit(2);
        }
        out.encoded = std::move(*encoded);
        out.rgb.clear();
      }
      p = std::make_shared<const std::string>(
          locus::rpc::ToProto(std::move(out)).SerializeAsString());
    }
    return p;
  }
};

class SimWorker {
 public:
  SimWorker(Shared& shared, int index, Behaviour behaviour)
      : s_(shared), index_(index), behaviour_(behaviour), rng_(static_cast<unsigned>(index) + 1) {
    connect();
  }

  // A connection of its own, as a worker on its own host has.
  void connect() {
    grpc::ChannelArguments args;
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
    args.SetMaxReceiveMessageSize(64 << 20);
    args.SetMaxSendMessageSize(64 << 20);
    channel_ = grpc::CreateCustomChannel(s_.address, grpc::InsecureChannelCredentials(), args);
    stub_ = v1::WorkerService::NewStub(channel_);
  }

  // Registers (blocking: done for all workers before the clock starts).
  bool start() {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    const v1::RegisterRequest req = registration();
    v1::RegisterResponse resp;
    const grpc::Status st = stub_->Register(&ctx, req, &resp);
    if (!st.ok()) {
      std::fprintf(stderr, "worker %d: Register: %s\n", index_, st.error_message().c_str());
      return false;
    }
    registered(resp);
    return true;
  }

  void poll() {
    if (s_.stopping || dead_) return;
    auto call = std::make_shared<Call<v1::GetTaskRequest, v1::GetTaskResponse>>(Ms(15000));
    call->req.set_worker_id(id_);
    call->req.set_wait_ms(10000);
    call->req.set_max_bands(s_.batch);
    track(call->ctx.get());
    {
      std::lock_guard lk(s_.mu);
      ++s_.get_tasks;
    }
    const auto sent = Clock::now();
    stub_->async()->GetTask(call->ctx.get(), &call->req, &call->resp,
                            [this, call, sent](grpc::Status st) {
                              untrack(call->ctx.get());
                              on_task(call->resp, st, sent);
                            });
  }

  // Heartbeats the band in hand, if any (the timer thread, every second).
  void heartbeat() {
    std::vector<std::string> leases;
    {
      std::lock_guard lk(mu_);
      leases = leases_;
    }
    if (leases.empty() || dead_ || behaviour_ != Behaviour::kNormal || s_.stopping) return;
    auto call = std::make_shared<Call<v1::HeartbeatRequest, v1::HeartbeatResponse>>(Ms(5000));
    call->req.set_worker_id(id_);
    for (const std::string& l : leases) call->req.add_lease_ids(l);
    track(call->ctx.get());
    stub_->async()->Heartbeat(call->ctx.get(), &call->req, &call->resp,
                              [this, call](grpc::Status) { untrack(call->ctx.get()); });
    std::lock_guard lk(s_.mu);
    ++s_.heartbeats;
  }

  // Ends every call in flight (the run is over).
  void stop() {
    std::lock_guard lk(mu_);
    for (grpc::ClientContext* c : in_flight_) c->TryCancel();
  }

  size_t in_flight() {
    std::lock_guard lk(mu_);
    return in_flight_.size();
  }

 private:
  template <typename Req, typename Resp>
  struct Call {
    explicit Call(Ms deadline) : ctx(std::make_unique<grpc::ClientContext>()) {
      ctx->set_deadline(std::chrono::system_clock::now() + deadline);
    }
    std::unique_ptr<grpc::ClientContext> ctx;
    Req req;
    Resp resp;
  };

  void track(grpc::ClientContext* c) {
    std::lock_guard lk(mu_);
    in_flight_.push_back(c);
  }
  void untrack(grpc::ClientContext* c) {
    std::lock_guard lk(mu_);
    in_flight_.erase(std::find(in_flight_.begin(), in_flight_.end(), c));
  }

  void retry_later() {
    s_.timers->at(Clock::now() + Ms(100), [this] { poll(); });
  }

  v1::RegisterRequest registration() const {
    v1::RegisterRequest req;
    req.set_name("sim-" + std::to_string(index_));
    req.set_threads(1);
    if (s_.png_deflate) req.add_encodings(v1::BAND_PNG8_DEFLATE);
    return req;
  }
  void registered(const v1::RegisterResponse& resp) {
    std::lock_guard lk(mu_);
    id_ = resp.worker_id();
    lease_ms_ = resp.lease_ms();
  }

  // Dropped by the coordinator (silent past its lease: a late worker):
  // register again and go on, as locus-worker does. Asynchronous: the
  // timer thread, which sends every worker's heartbeats, never waits for
  // the coordinator.
  void register_again() {
    if (s_.stopping) return;
    {
      std::lock_guard lk(s_.mu);
      ++s_.registrations;
    }
    auto call = std::make_shared<Call<v1::RegisterRequest, v1::RegisterResponse>>(Ms(30000));
    call->req = registration();
    track(call->ctx.get());
    stub_->async()->Register(
        call->ctx.get(), &call->req, &call->resp, [this, call](grpc::Status st) {
          untrack(call->ctx.get());
          if (st.ok()) {
            registered(call->resp);
            poll();
            return;
          }
          if (!outage(st)) {
            std::lock_guard lk(s_.mu);
            ++s_.errors;
            if (s_.errors <= 5)
              std::fprintf(stderr, "worker %d: Register: %s\n", index_, st.error_message().c_str());
          } else if (!s_.stopping) {
            register_again_later();  // the coordinator is away
          }
        });
  }
  void register_again_later() {
    s_.timers->at(Clock::now() + Ms(500), [this] { register_again(); });
  }

  // A call that failed because the coordinator is away (restarting), in a
  // run that expects it: counted apart, not as an error.
  bool outage(const grpc::Status& st) {
    if (!s_.outage_ok) return false;
    const auto code = st.error_code();
    if (code != grpc::StatusCode::UNAVAILABLE && code != grpc::StatusCode::DEADLINE_EXCEEDED &&
        code != grpc::StatusCode::CANCELLED)
      return false;
    std::lock_guard lk(s_.mu);
    ++s_.outage_errors;
    return true;
  }

  // A GetTask's answer, or (no `sent`) the one that came with a
  // CompleteBand's (CompleteBandResponse.next).
  void on_task(const v1::GetTaskResponse& resp, const grpc::Status& st,
               std::optional<Clock::time_point> sent) {
    if (s_.stopping) return;
    if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
      register_again();
      return;
    }
    if (!st.ok()) {
      if (!outage(st)) {
        std::lock_guard lk(s_.mu);
        ++s_.errors;
        if (s_.errors <= 5)
          std::fprintf(stderr, "worker %d: GetTask: %s\n", index_, st.error_message().c_str());
      }
      s_.timers->at(Clock::now() + Ms(100), [this] { poll(); });
      return;
    }
    if (!resp.has_task()) {
      poll();
      return;
    }
    // The band, and the further ones of a batch (--batch).
    std::vector<v1::BandTask> tasks{resp.task()};
    tasks.insert(tasks.end(), resp.more().begin(), resp.more().end());
    if (sent) {
      std::lock_guard lk(s_.mu);
      s_.dispatch_ms.push_back(seconds_since(*sent) * 1000);
    }
    {
      std::lock_guard lk(mu_);
      leases_.clear();
      for (const v1::BandTask& t : tasks) leases_.push_back(t.lease_id());
    }
    if (behaviour_ == Behaviour::kDie) {
      // A killed host: its connection goes, its band is never returned.
      dead_ = true;
      stop();
      if (s_.revive_ms > 0) {
        // ... and comes back (a restarted host): a new connection, a new
        // registration; it dies again after its next lease.
        s_.timers->at(Clock::now() + Ms(s_.revive_ms), [this] {
          if (s_.stopping) return;
          connect();
          has_scene_ = false;
          dead_ = false;
          {
            std::lock_guard lk(s_.mu);
            ++s_.revived;
          }
          register_again();
        });
      }
      return;
    }
    if (behaviour_ == Behaviour::kStall) {
      dead_ = true;  // alive, connected, silent
      return;
    }
    if (!has_scene_) {
      fetch_scene(std::move(tasks));
      return;
    }
    after_delay(std::move(tasks));
  }

  // The scene once per worker, as a real one fetches it once per hash.
  void fetch_scene(std::vector<v1::BandTask> tasks) {
    auto call = std::make_shared<Call<v1::GetSceneRequest, v1::GetSceneResponse>>(Ms(30000));
    call->req.set_worker_id(id_);
    call->req.set_scene_hash(tasks.front().scene_hash());
    track(call->ctx.get());
    stub_->async()->GetScene(call->ctx.get(), &call->req, &call->resp,
                             [this, call, tasks](grpc::Status st) {
                               untrack(call->ctx.get());
                               if (st.error_code() == grpc::StatusCode::NOT_FOUND &&
                                   st.error_message().find("unknown") != std::string::npos) {
                                 register_again();  // dropped meanwhile, as GetTask's answer
                                 return;
                               }
                               if (!st.ok()) {
                                 if (!outage(st)) {
                                   std::lock_guard lk(s_.mu);
                                   ++s_.errors;
                                 }
                                 retry_later();
                                 return;
                               }
                               {
                                 std::lock_guard lk(s_.mu);
                                 ++s_.scene_fetches;
                               }
                               has_scene_ = true;
                               after_delay(tasks);
                             });
  }

  // The bands rendered one after the other: the sum of their times.
  void after_delay(std::vector<v1::BandTask> tasks) {
    double ms = 0;
    for (size_t i = 0; i < tasks.size() && s_.delay_ms > 0; ++i) {
      double one = s_.delay_ms;
      if (s_.delay_sigma > 0) {
        // Log-normal with median `delay_ms`: real band times are skewed.
        std::lognormal_distribution<double> d(std::log(one), s_.delay_sigma);
        one = d(rng_);
      }
      ms += one;
    }
    if (behaviour_ == Behaviour::kLate) ms = static_cast<double>(lease_ms_) + 500;
    if (ms <= 0) {
      complete(tasks);
      return;
    }
    s_.timers->at(Clock::now() + std::chrono::microseconds(static_cast<int64_t>(ms * 1000)),
                  [this, tasks = std::move(tasks)] { complete(tasks); });
  }

  // Every band in hand in one call: the first as the request, the others
  // in its `more`.
  void complete(const std::vector<v1::BandTask>& tasks) {
    if (s_.stopping) return;
    auto call =
        std::make_shared<Call<v1::CompleteBandRequest, v1::CompleteBandResponse>>(Ms(30000));
    for (size_t i = 0; i < tasks.size(); ++i) {
      v1::CompleteBandRequest* one = i == 0 ? &call->req : call->req.add_more();
      one->ParseFromString(*s_.payload(tasks[i]));
      one->set_lease_id(tasks[i].lease_id());
    }
    call->req.set_worker_id(id_);
    call->req.set_want_next(s_.want_next);
    call->req.set_max_next(s_.batch);
    {
      std::lock_guard lk(s_.mu);
      ++s_.complete_calls;
    }
    track(call->ctx.get());
    const auto sent = Clock::now();
    stub_->async()->CompleteBand(call->ctx.get(), &call->req, &call->resp,
                                 [this, call, sent](grpc::Status st) {
                                   untrack(call->ctx.get());
                                   on_completed(*call, st, sent);
                                 });
  }

  void on_completed(const Call<v1::CompleteBandRequest, v1::CompleteBandResponse>& call,
                    const grpc::Status& st, Clock::time_point sent) {
    {
      std::lock_guard lk(mu_);
      leases_.clear();
    }
    if (st.error_code() == grpc::StatusCode::NOT_FOUND) {
      // The worker was dropped while it held the band: refused, as a result
      // for a lapsed lease is.
      {
        std::lock_guard lk(s_.mu);
        s_.refused += 1 + call.req.more_size();
      }
      register_again();
      return;
    }
    const bool away = !st.ok() && outage(st);
    {
      std::lock_guard lk(s_.mu);
      if (away) {
        // The coordinator went away with the band: its lease is void, the
        // band is rendered again.
      } else if (!st.ok()) {
        ++s_.errors;
        if (s_.errors <= 5)
          std::fprintf(stderr, "worker %d: CompleteBand: %s\n", index_, st.error_message().c_str());
      } else {
        // Each result of the call is judged alone (CompleteBandResponse.more).
        const int accepted = (call.resp.accepted() ? 1 : 0) +
                             static_cast<int>(std::count_if(
                                 call.resp.more().begin(), call.resp.more().end(),
                                 [](const v1::CompleteBandResponse& m) { return m.accepted(); }));
        s_.accepted += accepted;
        s_.refused += 1 + call.req.more_size() - accepted;
        if (accepted > 0) {
          s_.completion_ms.push_back(seconds_since(sent) * 1000);
          const auto now = Clock::now();
          if (s_.first_accept == Clock::time_point{}) s_.first_accept = now;
          s_.last_accept = now;
        }
      }
    }
    if (st.ok() && call.resp.has_next()) {
      {
        std::lock_guard lk(s_.mu);
        if (call.resp.next().has_task()) s_.with_answer += 1 + call.resp.next().more_size();
      }
      on_task(call.resp.next(), grpc::Status::OK, std::nullopt);
      return;
    }
    poll();
  }

  Shared& s_;
  const int index_;
  const Behaviour behaviour_;
  std::mt19937 rng_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::WorkerService::Stub> stub_;
  std::mutex mu_;
  std::string id_;
  int lease_ms_ = 5000;
  std::vector<std::string> leases_;  // the bands in hand
  std::vector<grpc::ClientContext*> in_flight_;
  std::atomic<bool> dead_{false};
  bool has_scene_ = false;  // touched by this worker's own callbacks only, one at a time
};

// ---------------------------------------------------------------- the checks

// Bands of the run's jobs accepted other than exactly once, from the store.
long bands_not_accepted_once(const std::string& db_path, long* bands_seen) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    std::fprintf(stderr, "%s: %s\n", db_path.c_str(), sqlite3_errmsg(db));
    sqlite3_close(db);
    return -1;
  }
  long bad = -1;
  sqlite3_stmt* st = nullptr;
  const char* sql = "SELECT count(*), coalesce(sum(completions != 1), 0) FROM bands";
  if (sqlite3_prepare_v2(db, sql, -1, &st, nullptr) == SQLITE_OK &&
      sqlite3_step(st) == SQLITE_ROW) {
    *bands_seen = sqlite3_column_int64(st, 0);
    bad = sqlite3_column_int64(st, 1);
  }
  sqlite3_finalize(st);
  sqlite3_close(db);
  return bad;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-farm-scale: one coordinator, many simulated workers"};
  std::string farm, data, scene_path, reference_out;
  int pid = 0, workers = 100, jobs = 4, frames = 5, width = 256, rows = 4, bands = 16;
  int die = 0, stall = 0, late = 0, timeout_s = 600;
  double delay_ms = 0, delay_sigma = 0;
  double measure_queued = 0;  // --measure-queued: seconds of sampling, then stop
  app.add_option("--farm", farm, "Coordinator address (loopback)")->required();
  app.add_option("--data", data, "The coordinator's --data directory (checked at the end)")
      ->required();
  app.add_option("--coordinator-pid", pid, "The coordinator's process (CPU, memory, files)");
  app.add_option("--scene", scene_path, "Scene file")->required();
  app.add_option("--workers", workers, "Simulated workers")->check(CLI::Range(1, 20000));
  app.add_option("--jobs", jobs, "Jobs")->check(CLI::Range(1, 10000));
  app.add_option("--frames", frames, "Frames per job")->check(CLI::Range(1, 100000));
  app.add_option("--bands", bands, "Bands per frame")->check(CLI::Range(1, 100000));
  app.add_option("--width", width, "Frame width")->check(CLI::Range(1, 8192));
  app.add_option("--rows", rows, "Rows per band")->check(CLI::Range(1, 8192));
  app.add_option("--delay-ms", delay_ms, "Time a worker takes per band (median); 0: none");
  app.add_option("--delay-sigma", delay_sigma, "Log-normal spread of that time; 0: fixed");
  bool no_next = false;
  bool no_png_deflate = false;
  int batch = 1;
  int revive_ms = 0;
  bool outage_ok = false;
  app.add_option("--revive-ms", revive_ms,
                 "A --die worker reconnects as a new worker after this long, and dies again after "
                 "its next lease (0: never)")
      ->check(CLI::Range(0, 3600000) & !CLI::Range(1, 999));
  app.add_flag("--outage-ok", outage_ok,
               "The coordinator restarts during the run: calls failed meanwhile are counted as "
               "outage_errors, not errors");
  app.add_option("--batch", batch,
                 "Bands per call: up to this many leased in one answer (GetTaskRequest.max_bands) "
                 "and returned together in one CompleteBand (CompleteBandRequest.more)")
      ->check(CLI::Range(1, 64));
  app.add_flag("--no-next", no_next,
               "Lease each band with a GetTask (not with the last result's answer)");
  app.add_flag("--no-png-deflate", no_png_deflate,
               "Do not offer png8+deflate: PNG jobs' bands travel as rgb8+zstd, the frames "
               "are encoded by the coordinator");
  app.add_option("--die", die, "Workers that drop their connection after their first lease");
  app.add_option("--stall", stall, "Workers that go silent after their first lease");
  app.add_option("--late", late, "Workers that return each band after its lease lapsed");
  app.add_option("--timeout", timeout_s, "Seconds before the run is called failed");
  app.add_option("--measure-queued", measure_queued,
                 "Big jobs (issue #25): after the submit, time `locus status` and sample the "
                 "coordinator's memory for this many seconds while the bands stay queued, then "
                 "stop without finishing the jobs");
  app.add_option("--reference-out", reference_out, "Write the reference frame here (PNG)");
  CLI11_PARSE(app, argc, argv);
  const int height = rows * bands;

  auto scene = locus::load_scene(scene_path);
  if (!scene.ok()) {
    std::fprintf(stderr, "%s\n", scene.status().message().c_str());
    return 2;
  }
  Shared shared;
  shared.address = farm;
  shared.width = width;
  shared.delay_ms = delay_ms;
  shared.delay_sigma = delay_sigma;
  shared.want_next = !no_next;
  shared.png_deflate = !no_png_deflate;
  shared.batch = batch;
  shared.revive_ms = revive_ms;
  shared.outage_ok = outage_ok;
  shared.scene = locus::scene_to_proto(*scene);

  // The reference: the frame through the worker's own renderer, once.
  locus::farm::SubmitRequest request;
  request.scene = shared.scene;
  request.scene_name = fs::path(scene_path).filename().string();
  request.width = width;
  request.height = height;
  request.frame_first = 1;
  request.frame_last = frames;
  request.bands = bands;
  request.output = "frame_####.png";
  {
    locus::farm::BandRenderer renderer(1);
    const std::string hash = locus::farm::content_hash(shared.scene.SerializeAsString());
    if (auto s = renderer.add_scene(hash, shared.scene, request.scene_name); !s.ok()) {
      std::fprintf(stderr, "%s\n", s.message().c_str());
      return 2;
    }
    locus::farm::BandLease whole;
    whole.scene_hash = hash;
    whole.frame = 1;
    whole.y0 = 0;
    whole.y1 = height;
    whole.width = width;
    whole.height = height;
    whole.frame_first = 1;
    whole.frame_last = frames;
    auto out = renderer.render(whole);
    if (!out.ok()) {
      std::fprintf(stderr, "reference: %s\n", out.status().message().c_str());
      return 2;
    }
    shared.frame = std::move(out->rgb);
  }
  locus::Image reference(width, height);
  reference.rgb = shared.frame;
  const std::string reference_path =
      reference_out.empty() ? (fs::path(data) / "reference.png").string() : reference_out;
  if (auto s = locus::write_image(reference_path, reference); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 2;
  }

  // The workers connect and register first; then the jobs arrive.
  Timers timers;
  shared.timers = &timers;
  std::vector<std::unique_ptr<SimWorker>> sims;
  for (int i = 0; i < workers; ++i) {
    Behaviour b = Behaviour::kNormal;
    if (i < die)
      b = Behaviour::kDie;
    else if (i < die + stall)
      b = Behaviour::kStall;
    else if (i < die + stall + late)
      b = Behaviour::kLate;
    sims.push_back(std::make_unique<SimWorker>(shared, i, b));
    if (!sims.back()->start()) return 1;
  }
  for (auto& w : sims) w->poll();
  std::printf("workers_connected %d\n", workers);
  const ProcessSample idle = sample(pid);
  std::printf("coordinator_rss_idle_mib %.1f\ncoordinator_fds_idle %d\n", idle.rss_kib / 1024.0,
              idle.fds);

  // The coordinator's CPU and the heartbeats count from before the first
  // submission: with many jobs, the workers render the first ones while the
  // last are still being submitted.
  const ProcessSample before = sample(pid);
  const double harness_before = own_cpu_seconds();
  std::atomic<bool> done{false};
  long peak_rss = 0;
  int peak_fds = 0;
  std::function<void()> beat = [&] {
    if (done) return;
    for (auto& w : sims) w->heartbeat();
    const ProcessSample p = sample(pid);
    peak_rss = std::max(peak_rss, p.rss_kib);
    peak_fds = std::max(peak_fds, p.fds);
    timers.at(Clock::now() + Ms(1000), beat);
  };
  if (measure_queued == 0) timers.at(Clock::now() + Ms(1000), beat);

  locus::client::FarmClient client(farm);
  std::vector<std::string> job_ids;
  const auto submit_start = Clock::now();
  for (int j = 0; j < jobs; ++j) {
    auto info = client.submit(request);
    if (!info.ok()) {
      std::fprintf(stderr, "submit: %s\n", info.status().message().c_str());
      return 1;
    }
    job_ids.push_back(info->job_id);
  }
  std::printf("submit_seconds %.3f\n", seconds_since(submit_start));
  if (measure_queued > 0) {
    // Big jobs: the status of one job and the list, timed; then the memory
    // while every worker holds a lease and the rest of the bands wait.
    const auto status_start = Clock::now();
    auto one = client.job(job_ids.front());
    std::printf("status_seconds %.3f\n", seconds_since(status_start));
    const auto list_start = Clock::now();
    auto all = client.jobs();
    std::printf("list_seconds %.3f\n", seconds_since(list_start));
    if (!one.ok() || !all.ok()) return 1;
    long peak = 0;
    const auto sampling = Clock::now();
    while (seconds_since(sampling) < measure_queued) {
      for (auto& w : sims) w->heartbeat();
      peak = std::max(peak, sample(pid).rss_kib);
      std::this_thread::sleep_for(Ms(250));
    }
    auto later = client.job(job_ids.front());
    if (!later.ok()) return 1;
    std::printf("bands_total %lld\nbands_done %lld\nbands_running %d\n",
                static_cast<long long>(later->spec.bands_total()),
                static_cast<long long>(later->bands_done), static_cast<int>(later->bands_running));
    std::printf("coordinator_rss_queued_mib %.1f\n", peak / 1024.0);
    std::fflush(stdout);
    std::_Exit(0);  // the simulated workers are not wound down
  }
  const auto start = Clock::now();

  bool all_done = false;
  std::vector<locus::farm::JobInfo> ended;
  // A client's view of the busy farm: each `locus status` of the polling
  // below, timed (a new call on the client's connection).
  std::vector<double> status_ms;
  while (seconds_since(start) < timeout_s) {
    ended.clear();
    bool unfinished = false;
    for (const std::string& id : job_ids) {
      const auto asked = Clock::now();
      auto info = client.job(id);
      status_ms.push_back(seconds_since(asked) * 1000);
      if (!info.ok()) {
        std::fprintf(stderr, "job %s: %s\n", id.c_str(), info.status().message().c_str());
        unfinished = true;
        break;
      }
      if (!locus::farm::is_terminal(info->state)) {
        unfinished = true;
        break;
      }
      ended.push_back(*info);
    }
    if (!unfinished) {
      all_done = true;
      break;
    }
    std::this_thread::sleep_for(Ms(100));
  }
  const ProcessSample after = sample(pid);
  const double harness_cpu = own_cpu_seconds() - harness_before;
  done = true;
  shared.stopping = true;
  for (auto& w : sims) w->stop();
  for (int i = 0; i < 100; ++i) {
    size_t n = 0;
    for (auto& w : sims) n += w->in_flight();
    if (n == 0) break;
    std::this_thread::sleep_for(Ms(50));
  }

  const int64_t total_bands = static_cast<int64_t>(jobs) * frames * bands;
  double window = 0;
  int64_t accepted = 0, refused = 0, errors = 0, fetches = 0, heartbeats = 0, registrations = 0;
  int64_t get_tasks = 0, with_answer = 0, outage_errors = 0, revived = 0, complete_calls = 0;
  std::vector<double> dispatch, completion;
  {
    std::lock_guard lk(shared.mu);
    window = std::chrono::duration<double>(shared.last_accept - shared.first_accept).count();
    accepted = shared.accepted;
    refused = shared.refused;
    errors = shared.errors;
    fetches = shared.scene_fetches;
    heartbeats = shared.heartbeats;
    registrations = shared.registrations;
    get_tasks = shared.get_tasks;
    outage_errors = shared.outage_errors;
    revived = shared.revived;
    with_answer = shared.with_answer;
    complete_calls = shared.complete_calls;
    dispatch = shared.dispatch_ms;
    completion = shared.completion_ms;
  }
  const double cpu = after.cpu_seconds - before.cpu_seconds;
  std::printf("bands %lld\naccepted %lld\nrefused %lld\nrpc_errors %lld\nscene_fetches %lld\n",
              static_cast<long long>(total_bands), static_cast<long long>(accepted),
              static_cast<long long>(refused), static_cast<long long>(errors),
              static_cast<long long>(fetches));
  std::printf("heartbeats %lld\nregistered_again %lld\n", static_cast<long long>(heartbeats),
              static_cast<long long>(registrations));
  // Calls per band: GetTask is saved for each band leased with an answer.
  std::printf("get_tasks %lld\nbands_with_answer %lld\ncomplete_calls %lld\n",
              static_cast<long long>(get_tasks), static_cast<long long>(with_answer),
              static_cast<long long>(complete_calls));
  std::printf("outage_errors %lld\nworkers_revived %lld\n", static_cast<long long>(outage_errors),
              static_cast<long long>(revived));
  std::printf("seconds %.3f\nbands_per_second %.0f\n", window,
              window > 0 ? static_cast<double>(accepted) / window : 0.0);
  std::printf("dispatch_ms_p50 %.3f\ndispatch_ms_p99 %.3f\ndispatch_ms_max %.3f\n",
              percentile(dispatch, 0.5), percentile(dispatch, 0.99), percentile(dispatch, 1.0));
  std::printf("completion_ms_p50 %.3f\ncompletion_ms_p99 %.3f\ncompletion_ms_max %.3f\n",
              percentile(completion, 0.5), percentile(completion, 0.99),
              percentile(completion, 1.0));
  std::printf("status_ms_p50 %.3f\nstatus_ms_max %.3f\n", percentile(status_ms, 0.5),
              percentile(status_ms, 1.0));
  if (pid > 0) {
    std::printf("coordinator_cpu_seconds %.3f\ncoordinator_cpu_us_per_band %.1f\n", cpu,
                accepted > 0 ? cpu * 1e6 / static_cast<double>(accepted) : 0.0);
    std::printf("coordinator_rss_peak_mib %.1f\ncoordinator_fds_peak %d\n", peak_rss / 1024.0,
                peak_fds);
  }
  // The simulated workers share the machine with the coordinator: what they
  // took of it bounds what the coordinator could have had.
  std::printf("harness_cpu_seconds %.3f\n", harness_cpu);
  std::printf("store_bytes %ju\n", tree_bytes(data));

  // What must hold, whatever the speed.
  int failures = 0;
  if (errors > 0) {
    std::printf("FAIL: %lld calls failed (other than a dropped worker's)\n",
                static_cast<long long>(errors));
    ++failures;
  }
  if (late > 0 && refused == 0) {
    std::printf("FAIL: --late workers, but no result was refused (a run shorter than a lease?)\n");
    ++failures;
  }
  if (!all_done) {
    std::printf("FAIL: jobs not finished after %d s\n", timeout_s);
    ++failures;
  }
  for (const auto& j : ended) {
    if (j.state != locus::farm::JobState::kSucceeded) {
      std::printf("FAIL: job %s %s: %s\n", j.job_id.c_str(), locus::farm::job_state_name(j.state),
                  j.error.c_str());
      ++failures;
    }
  }
  long bands_seen = 0;
  const long twice = bands_not_accepted_once((fs::path(data) / "locus.db").string(), &bands_seen);
  std::printf("store_bands %ld\nstore_bands_not_accepted_once %ld\n", bands_seen, twice);
  if (twice != 0 || bands_seen != total_bands) {
    std::printf("FAIL: the store has %ld bands (want %lld), %ld not accepted exactly once\n",
                bands_seen, static_cast<long long>(total_bands), twice);
    ++failures;
  }
  if (all_done) {
    int compared = 0;
    for (const std::string& id : job_ids) {
      for (int f = 1; f <= frames; ++f) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%04d.png", f);
        const std::string path = (fs::path(data) / "jobs" / id / name).string();
        auto got = locus::read_image(path);
        auto want = locus::read_image(reference_path);
        if (!got.ok() || !want.ok() || got->rgb != want->rgb) {
          std::printf("FAIL: %s differs from the reference (or is missing)\n", path.c_str());
          ++failures;
        } else {
          ++compared;
        }
      }
    }
    std::printf("frames_identical %d\n", compared);
  }
  std::printf("%s\n", failures == 0 ? "ok" : "FAILED");
  return failures == 0 ? 0 : 1;
}
