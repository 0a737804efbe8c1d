#include "common/farm/process.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

extern char** environ;

namespace locus::farm {
namespace {

std::string last_line_of(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  if (last.size() > 300) last = last.substr(0, 300) + "...";
  return last;
}

}  // namespace

Result<ProcessResult> run_process(const ProcessRun& run) {
  if (run.argv.empty()) return InvalidArgument("run_process: no program");
  // The environment: ours, with run.env set over it.
  std::map<std::string, std::string> env;
  for (char** e = environ; *e; ++e) {
    const std::string kv(*e);
    const size_t eq = kv.find('=');
    if (eq != std::string::npos) env[kv.substr(0, eq)] = kv.substr(eq + 1);
  }
  for (const auto& [k, v] : run.env) env[k] = v;
  std::vector<std::string> env_strings;
  for (const auto& [k, v] : env) env_strings.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (std::string& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::vector<std::string> args = run.argv;
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  const std::string out = run.output_path.empty() ? "/dev/null" : run.output_path;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return NotFound("cannot run " + run.argv[0] + ": " + std::strerror(rc));

  const auto deadline = SteadyClock::now() + run.timeout;
  int wstatus = 0;
  for (;;) {
    const pid_t done = ::waitpid(pid, &wstatus, WNOHANG);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) {
      return Internal("waiting for " + run.argv[0] + ": " + std::strerror(errno));
    }
    const bool stop = run.cancelled && run.cancelled();
    if (stop || SteadyClock::now() > deadline) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &wstatus, 0) < 0 && errno == EINTR) {
      }
      if (stop) return Status(Code::kCancelled, run.argv[0] + " was stopped");
      return Status(Code::kDeadlineExceeded, run.argv[0] + " took longer than " +
                                                 std::to_string(run.timeout.count() / 1000) +
                                                 " s and was stopped");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ProcessResult r;
  if (WIFEXITED(wstatus)) {
    r.exit_code = WEXITSTATUS(wstatus);
  } else if (WIFSIGNALED(wstatus)) {
    r.signal = WTERMSIG(wstatus);
  }
  if (!run.output_path.empty()) r.last_line = last_line_of(run.output_path);
  return r;
}

}  // namespace locus::farm
