#include "client/local_farm.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <thread>

#include "client/farm_client.h"
#include "common/farm/auth.h"

namespace locus::client {
namespace fs = std::filesystem;
namespace {

// The environment of a worker: this one's, with LOCUS_TOKEN set to the
// farm's token (never on a command line, which `ps` shows to every user).
std::vector<std::string> worker_environment(const std::string& token) {
  std::vector<std::string> env;
  for (char** e = environ; e && *e; ++e) {
    if (std::strncmp(*e, "LOCUS_TOKEN=", 12) != 0) env.emplace_back(*e);
  }
  env.push_back("LOCUS_TOKEN=" + token);
  return env;
}

pid_t spawn_worker(const std::string& binary, const std::string& address, int threads,
                   const std::string& log, const std::vector<std::string>& env) {
  // Built before fork: the child may only make async-signal-safe calls.
  std::vector<const char*> envp;
  for (const std::string& e : env) envp.push_back(e.c_str());
  envp.push_back(nullptr);
  const std::string threads_arg = std::to_string(threads);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid != 0) return pid;
  // Child: only async-signal-safe calls until exec. A worker must not
  // outlive the `locus` that started it, even when that one is killed.
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() != parent) _exit(1);
  const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    dup2(fd, 1);
    dup2(fd, 2);
    close(fd);
  }
  // Signals blocked in `locus` stay blocked across exec; unblock them.
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  const char* argv[] = {binary.c_str(),      "--coordinator", address.c_str(), "--threads",
                        threads_arg.c_str(), "--poll-ms",     "2000",          nullptr};
  execve(binary.c_str(), const_cast<char* const*>(argv), const_cast<char* const*>(envp.data()));
  _exit(127);
}

}  // namespace

Result<std::string> worker_binary() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return NotFound("cannot locate the running locus binary: " + ec.message());
  const fs::path worker = self.parent_path() / "locus-worker";
  if (access(worker.c_str(), X_OK) != 0) {
    return NotFound("locus-worker not found next to locus (looked for " + worker.string() +
                    "); build it, or render in process with --workers 0");
  }
  return worker.string();
}

bool local_farm_zips_exr(int workers, int threads, int cores) {
  return workers * (threads > 0 ? threads : cores) >= cores;
}

Result<std::unique_ptr<LocalFarm>> LocalFarm::start(const LocalFarmOptions& o) {
  auto binary = worker_binary();
  if (!binary.ok()) return binary.status();
  std::unique_ptr<LocalFarm> farm(new LocalFarm());
  std::string templ = (fs::temp_directory_path() / "locus-farm-XXXXXX").string();
  if (!mkdtemp(templ.data()))
    return Internal("cannot create a temporary directory for the local farm");
  farm->dir_ = templ;

  farm::CoordinatorOptions co;
  co.data_dir = farm->dir_;
  co.lease = o.lease;
  co.heartbeat = std::max(farm::Millis(50), o.lease / 5);
  // Its data directory is a temporary one, deleted at exit: nothing there
  // needs to outlive a power loss.
  co.fsync = false;
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  co.exr_zip = local_farm_zips_exr(o.workers, o.threads, cores);
  // Its one client is this process, with the scene `--workers 0` would
  // render: a shared coordinator's cap on a submission's objects (against
  // other users' jobs) does not apply. A scene too large for one gRPC
  // message is still refused at submit (docs/farm.md "Limits").
  co.limits.max_objects = std::numeric_limits<int>::max();
  farm->coordinator_ = std::make_unique<farm::Coordinator>(co);
  if (Status s = farm->coordinator_->start(); !s.ok()) return s;
  // Loopback only, plaintext (nothing leaves the host), and a fresh random
  // token for both roles: another user of this machine cannot use it.
  auto token = farm::random_token();
  if (!token.ok()) return token.status();
  farm->token_ = *token;
  rpc::ServerSecurity security;
  security.insecure = true;
  security.auth = farm::Authenticator::from_tokens({"local " + farm->token_}, {farm->token_});
  farm->server_ = std::make_unique<rpc::CoordinatorServer>(*farm->coordinator_);
  auto port = farm->server_->start("127.0.0.1:0", std::move(security));
  if (!port.ok()) return port.status();
  farm->address_ = "127.0.0.1:" + std::to_string(*port);
  if (o.dashboard) {
    rpc::HttpServerOptions http;
    http.address = "127.0.0.1:0";
    auto dashboard = farm->server_->serve_http(http);
    if (!dashboard.ok()) return dashboard.status();
    farm->dashboard_url_ =
        "http://127.0.0.1:" + std::to_string(*dashboard) + "/#token=" + farm->token_;
  }
  const std::vector<std::string> env = worker_environment(farm->token_);

  for (int i = 0; i < o.workers; ++i) {
    const std::string log =
        (fs::path(farm->dir_) / ("worker-" + std::to_string(i) + ".log")).string();
    const pid_t pid = spawn_worker(*binary, farm->address_, o.threads, log, env);
    if (pid < 0) return Internal("cannot start " + *binary);
    farm->pids_.push_back(pid);
  }
  farm->workers_ = o.workers;
  farm->monitor_ = std::thread([f = farm.get()] { f->monitor(); });
  return farm;
}

Status LocalFarm::wait_for_workers() {
  // The default split counts the registered workers; give them a moment.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (std::chrono::steady_clock::now() < until) {
    if (coordinator_->workers().size() >= static_cast<size_t>(workers_)) break;
    {
      std::lock_guard lk(mu_);
      if (pids_.empty())
        return Internal("every locus-worker exited at start; see the logs in " + dir_);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return Status::Ok();
}

void LocalFarm::monitor() {
  std::unique_lock lk(mu_);
  while (!stopping_) {
    if (stop_.wait_for(lk, std::chrono::milliseconds(50), [&] { return stopping_.load(); }))
      return;
    bool died = false;
    for (auto it = pids_.begin(); it != pids_.end();) {
      int status = 0;
      if (waitpid(*it, &status, WNOHANG) == *it) {
        spdlog::error("local worker {} exited ({}); its log is in {}", *it,
                      WIFSIGNALED(status) ? "signal " + std::to_string(WTERMSIG(status))
                                          : "status " + std::to_string(WEXITSTATUS(status)),
                      dir_);
        it = pids_.erase(it);
        died = true;
      } else {
        ++it;
      }
    }
    if (died) keep_ = true;
    if (died && pids_.empty()) {
      spdlog::error("no local worker is left: cancelling the job");
      for (const farm::JobInfo& j : coordinator_->jobs()) coordinator_->cancel(j.job_id);
    }
  }
}

LocalFarm::~LocalFarm() {
  {
    std::lock_guard lk(mu_);
    stopping_ = true;
  }
  stop_.notify_all();
  if (monitor_.joinable()) monitor_.join();
  // A farm whose logs are not kept has nothing left in its workers: the
  // job's frames are fetched (or it failed before one was rendered), and a
  // worker holds no state. They are killed at once; a SIGTERM would cost
  // every `locus render --workers N` some 15-20 ms waiting for them to
  // close their channels. Where the logs are kept (a failure), each worker
  // gets SIGTERM, so that its log ends with its own last words.
  for (pid_t pid : pids_) kill(pid, keep_ ? SIGTERM : SIGKILL);
  // Workers end their long poll at once on SIGTERM; a worker stuck in a
  // band past the grace period is killed.
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  for (pid_t pid : pids_) {
    for (;;) {
      int status = 0;
      if (waitpid(pid, &status, WNOHANG) != 0) break;
      if (std::chrono::steady_clock::now() > until) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        break;
      }
      // A killed worker is gone within a millisecond or so; a 5 ms step
      // cost each `locus render --workers N` 5-10 ms here.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }
  if (server_) server_->shutdown(farm::Millis(1000));
  if (coordinator_) coordinator_->shutdown();
  std::error_code ec;
  if (!keep_ && !dir_.empty()) fs::remove_all(dir_, ec);
}

}  // namespace locus::client
