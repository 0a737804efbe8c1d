// Frames of an animation that share their geometry (AnimationGeometry,
// common/prepare/prepared.h): where only the camera moves, every frame after
// the first is prepared on the first's primitives, hierarchy and solids, and
// renders the pixels a fresh preparation renders; where objects or lights
// move, or a surface is cut for the view, every frame is prepared afresh.
#include <gtest/gtest.h>

#include "common/farm/types.h"
#include "common/render.h"
#include "common/scene/scene_io.h"
#include "tests/render_compare.h"

namespace locus {
namespace {

constexpr int kFirst = 1, kLast = 4;
constexpr double kOrbit = 40.0;

Scene loaded(const std::string& path) {
  auto scene = load_scene(path);
  EXPECT_TRUE(scene.ok()) << scene.status().message();
  return scene.ok() ? *scene : Scene();
}

// SPD tetra (4,096 triangles in closed solids) whose camera moves by keys
// and turns by the orbit.
Scene moving_camera_scene() {
  Scene s = loaded(std::string(LOCUS_SHARED_DIR) + "/spd/def/tetra.nff");
  CameraKey a, b;
  a.frame = kFirst;
  a.angle = s.camera.angle;
  b.frame = kLast;
  b.angle = s.camera.angle * 0.8;
  b.at = s.camera.at + Vec3(0.05, 0.0, 0.02);
  s.animation.camera = {a, b};
  return s;
}

struct Frames {
  std::vector<std::vector<float>> pixels;
  std::vector<bool> reused;
  std::vector<std::shared_ptr<const SceneGeometry>> geometry;  // kept: no address reused
};

// Every frame at w x h through one AnimationGeometry.
Frames through_geometry(const Scene& source, int w, int h, const RenderParams& p) {
  AnimationGeometry shared(source);
  Frames out;
  for (int f = kFirst; f <= kLast; ++f) {
    const Camera view = farm::frame_camera(source, w, h, f, kFirst, kLast, kOrbit);
    bool reused = false;
    auto prepared = shared.prepare(
        view, [&] { return farm::frame_scene(source, w, h, f, kFirst, kLast, kOrbit); }, p,
        &reused);
    EXPECT_TRUE(prepared.ok()) << prepared.status().message();
    if (!prepared.ok()) return out;
    out.reused.push_back(reused);
    out.geometry.push_back((*prepared)->geometry());
    out.pixels.push_back(render_band(**prepared, Band{0, h}, p).pixels.rgb);
  }
  return out;
}

// Every frame prepared afresh, as before frames shared anything.
std::vector<std::vector<float>> afresh(const Scene& source, int w, int h, const RenderParams& p) {
  std::vector<std::vector<float>> out;
  for (int f = kFirst; f <= kLast; ++f) {
    auto r = render_image(farm::frame_scene(source, w, h, f, kFirst, kLast, kOrbit), p);
    EXPECT_TRUE(r.ok()) << r.status().message();
    out.push_back(r.ok() ? r->pixels.rgb : std::vector<float>());
  }
  return out;
}

TEST(AnimationGeometry, FramesOfAMovingCameraShareOneGeometryAndRenderTheSamePixels) {
  const Scene source = moving_camera_scene();
  for (const RenderParams& p :
       {testing_util::config_iv_params(2, 1), testing_util::raytrace_params(1),
        testing_util::shadow_rays_params(2), testing_util::config_iv_params(0, 2)}) {
    const Frames shared = through_geometry(source, 48, 40, p);
    ASSERT_EQ(shared.pixels.size(), 4u);
    EXPECT_EQ(shared.reused, (std::vector<bool>{false, true, true, true}));
    for (size_t i = 1; i < shared.geometry.size(); ++i)
      EXPECT_EQ(shared.geometry[i], shared.geometry[0]) << "frame " << i + kFirst;
    const auto fresh = afresh(source, 48, 40, p);
    for (size_t i = 0; i < fresh.size(); ++i) {
      EXPECT_EQ(shared.pixels[i], fresh[i]) << "frame " << i + kFirst;
      // The frames differ: each frame used its own camera.
      if (i > 0) {
        EXPECT_NE(shared.pixels[i], shared.pixels[i - 1]) << "frame " << i + kFirst;
      }
    }
  }
}

TEST(AnimationGeometry, FrameCameraIsTheFrameScenesCamera) {
  const Scene source = moving_camera_scene();
  for (int f = kFirst; f <= kLast; ++f) {
    const Camera a = farm::frame_camera(source, 64, 48, f, kFirst, kLast, kOrbit);
    const Camera b = farm::frame_scene(source, 64, 48, f, kFirst, kLast, kOrbit).camera;
    EXPECT_EQ(a.from, b.from);
    EXPECT_EQ(a.at, b.at);
    EXPECT_EQ(a.up, b.up);
    EXPECT_EQ(a.angle, b.angle);
    EXPECT_EQ(a.hither, b.hither);
    EXPECT_EQ(a.width, 64);
    EXPECT_EQ(a.height, 48);
    EXPECT_EQ(b.width, 64);
  }
}

TEST(AnimationGeometry, MovingObjectsLightsOrCurvedSurfacesArePreparedEveryFrame) {
  const RenderParams p = testing_util::config_iv_params(2, 1);
  Scene objects = moving_camera_scene();
  ObjectKey k0, k1;
  k0.frame = kFirst;
  k0.translate = Vec3(0, 0, 0);
  k1.frame = kLast;
  k1.translate = Vec3(0.1, 0, 0);
  objects.animation.objects = {ObjectTrack{0, {k0, k1}}};
  Scene lights = moving_camera_scene();
  ASSERT_FALSE(lights.lights.empty());
  lights.animation.lights = {
      LightTrack{0,
                 {LightKey{kFirst, lights.lights[0].position},
                  LightKey{kLast, lights.lights[0].position + Vec3(1, 0, 0)}}}};
  // The teapot's Bezier patches are cut into triangles for the view.
  Scene curved = loaded(std::string(LOCUS_SOURCE_DIR) + "/scenes/teapot.json");
  for (const Scene* source : {&objects, &lights, &curved}) {
    EXPECT_FALSE(AnimationGeometry(*source).shared());
    const Frames frames = through_geometry(*source, 40, 32, p);
    ASSERT_EQ(frames.pixels.size(), 4u);
    EXPECT_EQ(frames.reused, std::vector<bool>(4, false));
    EXPECT_NE(frames.geometry[1], frames.geometry[0]);
    const auto fresh = afresh(*source, 40, 32, p);
    for (size_t i = 0; i < fresh.size(); ++i) EXPECT_EQ(frames.pixels[i], fresh[i]);
  }
  EXPECT_TRUE(AnimationGeometry(moving_camera_scene()).shared());
}

TEST(AnimationGeometry, ANewBoxesSettingOrAReleaseBuildsTheGeometryAgain) {
  const Scene source = moving_camera_scene();
  AnimationGeometry shared(source);
  auto frame = [&] { return farm::frame_scene(source, 32, 32, 1, kFirst, kLast, kOrbit); };
  const Camera view = farm::frame_camera(source, 32, 32, 1, kFirst, kLast, kOrbit);
  RenderParams boxes = testing_util::raytrace_params(1);
  RenderParams none = boxes;
  none.boxes = Boxes::kNone;
  bool reused = true;
  auto a = shared.prepare(view, frame, boxes, &reused);
  ASSERT_TRUE(a.ok());
  EXPECT_FALSE(reused);
  auto b = shared.prepare(view, frame, none, &reused);
  ASSERT_TRUE(b.ok());
  EXPECT_FALSE(reused);  // no hierarchy wanted: built again, without one
  EXPECT_TRUE((*b)->bvh.nodes.empty());
  EXPECT_FALSE((*a)->bvh.nodes.empty());
  auto c = shared.prepare(view, frame, none, &reused);
  ASSERT_TRUE(c.ok());
  EXPECT_TRUE(reused);
  shared.release();
  auto d = shared.prepare(view, frame, none, &reused);
  ASSERT_TRUE(d.ok());
  EXPECT_FALSE(reused);
  EXPECT_EQ(render_band(**d, Band{0, 32}, none).pixels.rgb,
            render_band(**c, Band{0, 32}, none).pixels.rgb);
}

TEST(AnimationGeometry, AFrameWithoutPixelsIsRefusedEvenOnASharedGeometry) {
  const Scene source = moving_camera_scene();
  AnimationGeometry shared(source);
  const RenderParams p = testing_util::raytrace_params(1);
  auto frame = [&] { return farm::frame_scene(source, 16, 16, 1, kFirst, kLast, kOrbit); };
  ASSERT_TRUE(
      shared.prepare(farm::frame_camera(source, 16, 16, 1, kFirst, kLast, kOrbit), frame, p).ok());
  Camera empty = farm::frame_camera(source, 16, 16, 2, kFirst, kLast, kOrbit);
  empty.width = 0;
  bool reused = true;
  auto r = shared.prepare(empty, frame, p, &reused);
  EXPECT_EQ(r.status().code(), Code::kInvalidArgument);
  EXPECT_FALSE(reused);
}

}  // namespace
}  // namespace locus
