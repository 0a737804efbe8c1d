// Test doubles for the Scheduler and the Coordinator without a network,
// shared by scheduler_test, store_test, operations_test and metrics_test: a
// clock the test moves, a job's spec, a worker's pixels for a leased band,
// and a temporary directory.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "common/farm/types.h"

namespace locus::farm::test_doubles {

struct FakeClock {
  TimePoint t{};
  NowFn fn() {
    return [this] { return t; };
  }
  void advance(int ms) { t += Millis(ms); }
};

// A job of w x h pixels, frames first..last, `bands` bands per frame, as
// the Scheduler takes it after the coordinator's checks.
inline JobSpec job_spec(int w, int h, int first, int last, int bands,
                        const std::string& output = "shot_####.png") {
  JobSpec s;
  s.scene_hash = "hash";
  s.scene_name = "test";
  s.width = w;
  s.height = h;
  s.frame_first = first;
  s.frame_last = last;
  s.bands = bands;
  s.output = output;
  return s;
}

// The band's pixels, all 0.5: the right size for its lease.
inline BandOutput pixels(const std::string& worker, const BandLease& t) {
  BandOutput o;
  o.worker_id = worker;
  o.lease_id = t.lease_id;
  o.rgb.assign(static_cast<size_t>(t.width) * (t.y1 - t.y0) * 3, 0.5f);
  o.stats.pixels_total = static_cast<uint64_t>(t.width) * (t.y1 - t.y0);
  o.stats.geometry_triangles = 100;  // each band's frame: summed as a maximum
  return o;
}

// A fresh directory under the system's temporary one, removed with it.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    std::string t = (std::filesystem::temp_directory_path() / "locus-store-test-XXXXXX").string();
    EXPECT_NE(mkdtemp(t.data()), nullptr);
    path = t;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
};

}  // namespace locus::farm::test_doubles
