// Cost maps on the farm (issue #27 item 5; docs/cost-map.md "On the
// farm"): the workers count each band's work per pixel, the coordinator
// joins the bands' counts and writes the picture beside each frame, the
// client fetches it. The map a farm writes is the picture of the very
// counts each band's own render makes (render_band with a cost buffer, the
// job's band edges), joined: compared numerically with one made here.
#include <gtest/gtest.h>

#include "common/base/cost_map.h"
#include "common/prepare/prepared.h"
#include "tests/farm_fixture.h"

namespace locus::farm::testing_farm {
namespace {

const std::string kD = std::string(LOCUS_SOURCE_DIR) + "/scenes/paper/d_spheres_2lights.json";

// The cost counts of frame `frame` of a job as its bands render them.
CostBuffer bands_counts(const SubmitRequest& r, const JobSpec& spec, int frame) {
  auto scene = load_scene(r.scene_name);
  EXPECT_TRUE(scene.ok());
  auto params = to_render_params(spec.render, 1);
  EXPECT_TRUE(params.ok());
  auto prepared = prepare_scene(
      frame_scene(*scene, r.width, r.height, frame, r.frame_first, r.frame_last, r.orbit_degrees),
      *params);
  EXPECT_TRUE(prepared.ok());
  CostBuffer all;
  all.reset(r.width, 0, r.height);
  for (int b = 0; b < spec.bands; ++b) {
    CostBuffer part;
    render_band(**prepared, band_rows(spec, b), *params, nullptr, &part);
    std::copy(part.pixels.begin(), part.pixels.end(),
              all.pixels.begin() + static_cast<size_t>(part.y0) * r.width);
  }
  return all;
}

// The largest difference of two images' values (1 if their sizes differ).
double max_difference(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) return 1;
  double worst = 0;
  for (size_t i = 0; i < a.rgb.size(); ++i)
    worst = std::max(worst, std::abs(double{a.rgb[i]} - b.rgb[i]));
  return worst;
}

TEST_F(FarmTest, CostMapsAreTheBandsOwnCountsJoined) {
  start();
  add_workers(2);
  SubmitRequest r = request(kD, 96, 72, 1, 2, 5, "f_####.png");
  r.cost_map = "maps/c_####.png";  // the coordinator keeps the file name
  const JobInfo job = run(r);
  ASSERT_EQ(job.state, JobState::kSucceeded) << job.error;
  EXPECT_EQ(job.spec.cost_map, "c_####.png");
  auto spec = coordinator_->job(job.job_id);
  ASSERT_TRUE(spec.ok());
  const fs::path got = dir_ / "got";
  auto maps = client_->fetch(
      job.job_id, {}, [&](int, const std::string& name) { return (got / name).string(); },
      /*cost_maps=*/true);
  ASSERT_TRUE(maps.ok()) << maps.status().message();
  ASSERT_EQ(maps->size(), 2u);
  Stats counted;
  for (int f = 1; f <= 2; ++f) {
    SCOPED_TRACE(f);
    const CostBuffer counts = bands_counts(r, spec->spec, f);
    counted += counts.totals();
    const fs::path mine = dir_ / ("mine_" + std::to_string(f) + ".png");
    ASSERT_TRUE(write_image(mine.string(), cost_map_image(counts), true).ok());
    auto want = read_image(mine.string());
    auto farm = read_image((got / frame_path("c_####.png", f)).string());
    ASSERT_TRUE(want.ok() && farm.ok());
    EXPECT_EQ(max_difference(*farm, *want), 0.0);
    // Not a blank picture: the spheres' ray-traced spans are outlined.
    int cyan = 0;
    for (int i = 0; i < farm->width * farm->height; ++i) {
      const float* p = &farm->rgb[static_cast<size_t>(i) * 3];
      cyan += p[0] == 0.0f && p[1] == 1.0f && p[2] == 1.0f;
    }
    EXPECT_GT(cyan, 50);
  }
  // The counts are the ones the workers reported as the job's stats.
  EXPECT_GT(counted.rays_eye, 0u);
  EXPECT_EQ(counted.rays_eye, job.stats.rays_eye);
  EXPECT_EQ(counted.rays_reflected, job.stats.rays_reflected);
  EXPECT_EQ(counted.rays_shadow, job.stats.rays_shadow);
  EXPECT_EQ(counted.tests_shadow_volume, job.stats.tests_shadow_volume);
  // The frames themselves are the single process's, as without a map.
  expect_identical(job, r);

  // One band: the farm's map is the in-process `locus render --cost-map`'s
  // (render_image with a cost buffer), EXR and all.
  SubmitRequest one = request(kD, 80, 60, 1, 1, 1, "g_####.exr");
  one.cost_map = "k_####.exr";
  const JobInfo single = run(one);
  ASSERT_EQ(single.state, JobState::kSucceeded) << single.error;
  auto fetched = client_->fetch(
      single.job_id, {}, [&](int, const std::string& name) { return (got / name).string(); }, true);
  ASSERT_TRUE(fetched.ok()) << fetched.status().message();
  auto scene = load_scene(kD);
  ASSERT_TRUE(scene.ok());
  CostBuffer cost;
  auto here = render_image(frame_scene(*scene, 80, 60, 1, 1, 1, 0),
                           *to_render_params(one.render, 1), &cost);
  ASSERT_TRUE(here.ok());
  auto farm_map = read_image((got / "k_0001.exr").string());
  ASSERT_TRUE(farm_map.ok());
  EXPECT_EQ(max_difference(*farm_map, cost_map_image(cost)), 0.0);

  // A job without cost maps has none to fetch, and says why.
  const JobInfo plain = run(request(kD, 32, 24, 1, 1, 2, "p_####.png"));
  auto none = client_->fetch(
      plain.job_id, {}, [&](int, const std::string& name) { return (got / name).string(); }, true);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.status().message().find("makes no cost maps"), std::string::npos)
      << none.status().message();
  EXPECT_FALSE(fs::exists(coordinator_->job_dir(plain.job_id) + "/c_0001.png"));
}

TEST_F(FarmTest, BadCostMapPatternsAreRefusedAtSubmit) {
  start();
  const auto refused = [&](const std::string& pattern, int frames, const std::string& words) {
    SubmitRequest r = request(kD, 32, 24, 1, frames, 1, "f_####.png");
    r.cost_map = pattern;
    auto job = client_->submit(r);
    ASSERT_FALSE(job.ok()) << pattern;
    EXPECT_EQ(job.status().code(), Code::kInvalidArgument);
    EXPECT_NE(job.status().message().find("cost map"), std::string::npos) << job.status().message();
    EXPECT_NE(job.status().message().find(words), std::string::npos) << job.status().message();
  };
  refused("../c_####.png", 1, "..");
  refused("/tmp/c_####.png", 1, "absolute");
  refused("c_####.jpg", 1, "unsupported image type");
  refused("c.png", 2, "frame number field");
  refused("out/f_####.png", 1, "the frames' file name");
  refused("c_####\x01.png", 1, "control characters");
  EXPECT_TRUE(coordinator_->jobs().empty());
}

}  // namespace
}  // namespace locus::farm::testing_farm
