#include "client/local_farm.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
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

// Starts a worker that reads the coordinator's address from `address_fd`
// (its end of a socket pair, close-on-exec in this process), so that it
// loads while the coordinator starts.
pid_t spawn_worker(const std::string& binary, int address_fd, int threads, const std::string& log,
                   const std::vector<std::string>& env) {
  // Built before fork: the child may only make async-signal-safe calls.
  std::vector<const char*> envp;
  for (const std::string& e : env) envp.push_back(e.c_str());
  envp.push_back(nullptr);
  const std::string threads_arg = std::to_string(threads);
  const std::string fd_arg = std::to_string(address_fd);
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
  // The address socket is the one descriptor the worker inherits.
  fcntl(address_fd, F_SETFD, 0);
  // Signals blocked in `locus` stay blocked across exec; unblock them.
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  const char* argv[] = {binary.c_str(),      "--coordinator-fd", fd_arg.c_str(), "--threads",
                        threads_arg.c_str(), "--poll-ms",        "2000",         nullptr};
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

  // Loopback only, plaintext (nothing leaves the host), and a fresh random
  // token for both roles: another user of this machine cannot use it.
  auto token = farm::random_token();
  if (!token.ok()) return token.status();
  farm->token_ = *token;
  // The workers start first and load (the dynamic linker is most of a
  // worker's start) while the coordinator starts; each waits on a socket
  // for its address. A farm that fails to start closes them unwritten, and
  // its workers exit.
  const std::vector<std::string> env = worker_environment(farm->token_);
  std::vector<int> address_fds;
  struct CloseFds {
    std::vector<int>& fds;
    ~CloseFds() {
      for (int fd : fds) close(fd);
    }
  } close_fds{address_fds};
  for (int i = 0; i < o.workers; ++i) {
    // A socket pair rather than a pipe: send() with MSG_NOSIGNAL to a
    // worker that is gone is EPIPE, not SIGPIPE.
    int fds[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0)
      return Internal(std::string("cannot make a socket pair for a local worker: ") +
                      std::strerror(errno));
    const std::string log =
        (fs::path(farm->dir_) / ("worker-" + std::to_string(i) + ".log")).string();
    const pid_t pid = spawn_worker(*binary, fds[0], o.threads, log, env);
    close(fds[0]);
    if (pid < 0) {
      close(fds[1]);
      return Internal("cannot start " + *binary);
    }
    address_fds.push_back(fds[1]);
    farm->pids_.push_back(pid);
  }

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
  rpc::ServerSecurity security;
  security.insecure = true;
  security.auth =
      farm::Authenticator::from_tokens({std::string(kUser) + " " + farm->token_}, {farm->token_});
  farm->server_ = std::make_unique<rpc::CoordinatorServer>(*farm->coordinator_);
  auto port = farm->server_->start("127.0.0.1:0", std::move(security));
  if (!port.ok()) return port.status();
  farm->address_ = "127.0.0.1:" + std::to_string(*port);
  // The coordinator listens: the workers may dial it.
  const std::string line = farm->address_ + "\n";
  for (int fd : address_fds) {
    // Far below a socket's buffer: sent whole, without waiting. A worker
    // that is gone already (EPIPE) is reaped by the monitor.
    if (send(fd, line.data(), line.size(), MSG_NOSIGNAL) < 0) {
      spdlog::warn("a local worker did not take the coordinator's address: {}",
                   std::strerror(errno));
    }
  }
  if (o.dashboard) {
    rpc::HttpServerOptions http;
    http.address = "127.0.0.1:0";
    auto dashboard = farm->server_->serve_http(http);
    if (!dashboard.ok()) return dashboard.status();
    farm->dashboard_url_ =
        "http://127.0.0.1:" + std::to_string(*dashboard) + "/#token=" + farm->token_;
  }
  farm->workers_ = o.workers;
  farm->monitor_ = std::thread([f = farm.get()] { f->monitor(); });
  return farm;
}

Result<farm::JobInfo> LocalFarm::submit(const farm::SubmitRequest& request) {
  return coordinator_->submit(request, kUser);
}

Result<std::vector<std::string>> LocalFarm::fetch(const std::string& job_id, const FileDest& dest,
                                                  bool cost_maps) {
  FetchedFiles files(dest, "the local farm");
  const Status s = coordinator_->fetch(
      job_id, farm::Caller{kUser, false}, {},
      [&files](const farm::FileChunk& c) { return files.take(c); }, cost_maps);
  if (!files.status().ok()) return files.status();
  if (!s.ok()) return s;
  return files.written();
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

void LocalFarm::end_workers() {
  // The monitor first, so that it neither reaps nor reports the workers
  // ended here.
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
  // band past the grace period is killed. Each is reaped here, not left to
  // whatever adopts it: a container's first process may never reap, and
  // each `locus render` would leave zombies there. (Ignoring SIGCHLD
  // instead would not wait, but a worker that dies after this process has
  // exited is then its adopter's to reap.)
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
  pids_.clear();
}

void LocalFarm::remove_dir() {
  std::error_code ec;
  if (!keep_ && !dir_.empty()) fs::remove_all(dir_, ec);
}

void LocalFarm::exit_process(int code) {
  end_workers();
  remove_dir();
  spdlog::default_logger()->flush();
  std::fflush(nullptr);
  std::_Exit(code);
}

LocalFarm::~LocalFarm() {
  end_workers();
  if (server_) server_->shutdown(farm::Millis(1000));
  if (coordinator_) coordinator_->shutdown();
  remove_dir();
}

}  // namespace locus::client
