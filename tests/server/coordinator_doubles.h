// Test doubles for whole Coordinators without a network, shared by
// store_test, upgrade_test, backup_test and bad_results_test: release
// 0.13's data directory, a worker
// played by the test (real pixels through the worker's renderer, over the
// Coordinator's own API), waiting for a job's end, and a frame rendered in
// one process from the scene the coordinator holds.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>
#include <thread>

#include "common/render.h"
#include "common/scene/scene_io.h"
#include "server/coordinator.h"
#include "worker/band_renderer.h"

namespace locus::farm::test_doubles {

// A Coordinator's options for a test: its data under dir/data, a fast
// tick, no syncs (a test of durability turns them on).
inline CoordinatorOptions test_options(const std::filesystem::path& dir) {
  CoordinatorOptions o;
  o.data_dir = (dir / "data").string();
  o.tick = Millis(10);
  o.fsync = false;
  return o;
}

// A data directory written by release 0.13 (its README says how).
inline const std::filesystem::path kStoreV013 =
    std::filesystem::path(LOCUS_SOURCE_DIR) / "tests/data/store-v0.13/data";

struct TestWorker {
  Coordinator* c;
  std::string id;
  BandRenderer renderer{1};

  TestWorker(Coordinator& coordinator, const std::string& name)
      : c(&coordinator), id(coordinator.register_worker(name, 1)->worker_id) {}

  std::optional<BandLease> take() {
    auto t = c->lease_band(id, Millis(0), nullptr);
    EXPECT_TRUE(t.ok()) << t.status().message();
    return t.ok() ? *t : std::nullopt;
  }
  BandOutput render(const BandLease& t) {
    if (!renderer.has_scene(t.scene_hash)) {
      auto scene = c->get_scene(id, t.scene_hash);
      EXPECT_TRUE(scene.ok());
      EXPECT_TRUE(renderer.add_scene_bytes(t.scene_hash, **scene, "test").ok());
    }
    auto out = renderer.render(t);
    EXPECT_TRUE(out.ok()) << out.status().message();
    out->worker_id = id;
    out->lease_id = t.lease_id;
    return *out;
  }
  bool complete(const BandLease& t) {
    auto r = c->complete_band(render(t));
    EXPECT_TRUE(r.ok()) << r.status().message();
    return r.ok() && r->accepted;
  }
};

inline JobInfo wait_for_end(Coordinator& c, const std::string& job) {
  for (int i = 0; i < 1000; ++i) {
    auto j = c.job(job);
    if (j.ok() && is_terminal(j->state)) return *j;
    std::this_thread::sleep_for(Millis(10));
  }
  ADD_FAILURE() << "job " << job << " did not end";
  return *c.job(job);
}

// The job's frame rendered in one process from the scene as the
// coordinator keeps it (its workers get the same).
inline Image single_process_frame(const v1::Scene& proto, const JobSpec& spec, int frame) {
  auto scene = scene_from_proto(proto, spec.scene_name);
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  if (!scene.ok()) return Image();
  const Scene s = frame_scene(*scene, spec.width, spec.height, frame, spec.frame_first,
                              spec.frame_last, spec.orbit_degrees);
  auto image = render_image(s, *to_render_params(spec.render, 1));
  EXPECT_TRUE(image.ok()) << image.status().message();
  return image.ok() ? image->pixels : Image();
}

}  // namespace locus::farm::test_doubles
