// Telling that a job ended (issue #26 item 2, docs/farm.md "Notifications"):
// a job's --notify-url gets an HTTP POST of its final status as JSON (the
// JobStatus of docs/http-api.md), retried with back-off; the coordinator's
// --notify-cmd runs for every job that ends, with the job in its
// environment. One thread, outside the coordinator's lock; what happened
// goes to the job's history (`locus events`), and a restart tells what a
// stop left untold (Coordinator::on_job_ended).
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "common/base/status.h"
#include "common/farm/types.h"
#include "server/coordinator.h"

namespace locus::rpc {

struct NotifierOptions {
  // --notify-cmd: run with /bin/sh -c for every job that ends, with
  // LOCUS_JOB_ID, LOCUS_JOB_STATE, LOCUS_JOB_KIND, LOCUS_JOB_OWNER,
  // LOCUS_JOB_ERROR and LOCUS_JOB_DIR (its frames) in its environment.
  std::string command;
  std::chrono::milliseconds command_timeout{60000};
  // The POST: attempts, the wait after the first failure (doubled after
  // each), and the time one attempt may take.
  int attempts = 6;
  std::chrono::milliseconds first_backoff{1000};
  std::chrono::milliseconds timeout{10000};
};

class Notifier {
 public:
  // Registers with the coordinator (before its start()).
  Notifier(farm::Coordinator& coordinator, NotifierOptions options);
  ~Notifier();  // stops; what is left untold is told after the next start
  Notifier(const Notifier&) = delete;
  Notifier& operator=(const Notifier&) = delete;

  // The JSON body of a job's notification.
  static std::string body(const farm::JobInfo& job);
  // One POST of `body` to `url`: OK for a 2xx answer; otherwise the
  // problem ("HTTP 500", "connection refused").
  static Status post(const std::string& url, const std::string& body,
                     std::chrono::milliseconds timeout);

 private:
  struct Pending {
    farm::JobInfo job;
    int attempt = 0;  // POSTs made
    bool command_done = false;
    std::chrono::steady_clock::time_point due;
  };
  void enqueue(const farm::JobInfo& job);
  void loop();
  // One step of a notice; true when nothing is left to do for it.
  bool step(Pending& p);
  Status run_command(const farm::JobInfo& job);

  farm::Coordinator& coordinator_;
  NotifierOptions options_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Pending> queue_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace locus::rpc
