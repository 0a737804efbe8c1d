// locus-dashboard-watchers: N open dashboards against a coordinator's --http
// port (bench/dashboard/run.sh runs it). Each watcher is what the page
// does: once a second GET /api/v1/farm?since=V with its own cursor, and
// when the farm changed, GET /api/v1/jobs/J as the job page does. Plain
// sockets (HTTP/1.1, one connection per request as the server wants), a
// thread per watcher that sleeps between polls, so that the watchers
// themselves cost little CPU. Runs until killed or --seconds; prints
// "key value" lines: requests, changed answers, errors.
#include <arpa/inet.h>
#include <csignal>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "tests/raw_http.h"

namespace {

using Clock = std::chrono::steady_clock;
std::atomic<bool> g_stop{false};  // SIGTERM, SIGINT: finish and report
extern "C" void on_signal(int) { g_stop = true; }

// One request and its whole answer ("" when the connection failed).
std::string get(const sockaddr_in& to, const std::string& path, const std::string& token) {
  return locus::testing::raw_http(to, "GET " + path + " HTTP/1.1\r\nHost: bench\r\nAuthorization: Bearer " +
                                          token + "\r\nConnection: close\r\n\r\n");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"locus-dashboard-watchers: open dashboards polling a coordinator"};
  std::string address = "127.0.0.1:7080", token, job;
  int watchers = 200;
  double seconds = 60, period = 1.0;
  app.add_option("--http", address, "The coordinator's --http HOST:PORT (IPv4)");
  app.add_option("--token", token, "A client token")->required();
  app.add_option("--job", job, "A job to follow as the job page does");
  app.add_option("--watchers", watchers, "Open dashboards")->check(CLI::Range(1, 10000));
  app.add_option("--seconds", seconds, "How long");
  app.add_option("--period", period, "Seconds between a watcher's polls");
  CLI11_PARSE(app, argc, argv);
  const size_t colon = address.rfind(':');
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(std::stoi(address.substr(colon + 1))));
  if (::inet_pton(AF_INET, address.substr(0, colon).c_str(), &to.sin_addr) != 1) {
    std::fprintf(stderr, "--http %s: not an IPv4 address\n", address.c_str());
    return 2;
  }
  std::atomic<long> requests{0}, changed{0}, errors{0};
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(seconds));
  std::vector<std::thread> threads;
  for (int i = 0; i < watchers; ++i) {
    threads.emplace_back([&, i] {
      std::string version = "0";
      // Spread over the period, as pages opened at different moments are.
      auto next = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                     std::chrono::duration<double>(period * i / watchers));
      while (!g_stop && Clock::now() < end) {
        std::this_thread::sleep_until(next);
        next += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period));
        const std::string farm = get(to, "/api/v1/farm?since=" + version, token);
        ++requests;
        if (farm.rfind("HTTP/1.1 200", 0) != 0) {
          if (errors++ == 0) {
            std::fprintf(stderr, "first error: %s\n", farm.substr(0, farm.find('\r')).c_str());
          }
          continue;
        }
        const size_t v = farm.find("\"version\":\"");
        if (v != std::string::npos) {
          version = farm.substr(v + 11, farm.find('"', v + 11) - v - 11);
        }
        if (farm.find("\"unchanged\":true") != std::string::npos) continue;
        ++changed;
        if (!job.empty()) {
          const std::string j = get(to, "/api/v1/jobs/" + job, token);
          ++requests;
          // 404: the job is not submitted yet (the watchers open first).
          if (j.rfind("HTTP/1.1 200", 0) != 0 && j.rfind("HTTP/1.1 404", 0) != 0) ++errors;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  std::printf("watchers %d\nrequests %ld\nchanged %ld\nerrors %ld\n", watchers, requests.load(),
              changed.load(), errors.load());
  return errors.load() == 0 ? 0 : 1;
}
