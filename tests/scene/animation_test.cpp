// Keyframe interpolation, the orbit, frame patterns, and the proto round
// trip of animations.
#include "common/scene/animation.h"

#include <gtest/gtest.h>

#include "common/scene/scene.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus {
namespace {

Scene two_objects() {
  Scene s;
  s.has_camera = true;
  s.camera.from = Vec3(0, 0, 10);
  s.camera.at = Vec3(0, 0, 0);
  s.lights.push_back(Light{Vec3(1, 2, 3), std::nullopt});
  s.materials.push_back(Material{});
  Object a;
  a.shape = Sphere{Vec3(0, 0, 0), 1.0};
  a.world_from_object = Mat4(2.0);
  a.world_from_object[3][3] = 1.0;
  s.objects.push_back(a);
  s.objects.push_back(a);
  return s;
}

TEST(Animation, StillSceneComesBackBitIdentical) {
  const Scene s = two_objects();
  const Scene f = scene_at_frame(s, 17, Orbit{0.0, 1, 30});
  EXPECT_EQ(f.camera.from, s.camera.from);
  EXPECT_EQ(f.objects[0].world_from_object, s.objects[0].world_from_object);
  EXPECT_EQ(f.lights[0].position, s.lights[0].position);
}

TEST(Animation, CameraKeysInterpolateLinearlyAndHold) {
  Scene s = two_objects();
  CameraKey k1;
  k1.frame = 1;
  k1.from = Vec3(0, 0, 10);
  k1.angle = 30;
  CameraKey k2;
  k2.frame = 11;
  k2.from = Vec3(10, 0, 10);
  k2.angle = 50;
  s.animation.camera = {k1, k2};
  EXPECT_EQ(scene_at_frame(s, 0).camera.from, Vec3(0, 0, 10));
  EXPECT_EQ(scene_at_frame(s, 1).camera.from, Vec3(0, 0, 10));
  EXPECT_DOUBLE_EQ(scene_at_frame(s, 6).camera.from.x, 5.0);
  EXPECT_DOUBLE_EQ(scene_at_frame(s, 6).camera.angle, 40.0);
  EXPECT_EQ(scene_at_frame(s, 11).camera.from, Vec3(10, 0, 10));
  EXPECT_EQ(scene_at_frame(s, 50).camera.from, Vec3(10, 0, 10));
  EXPECT_EQ(scene_at_frame(s, 6).camera.at, s.camera.at);  // not keyed: untouched

  s.animation.interpolation = Interpolation::kSmooth;
  EXPECT_DOUBLE_EQ(scene_at_frame(s, 6).camera.from.x, 5.0);  // smoothstep(1/2) = 1/2
  EXPECT_LT(scene_at_frame(s, 3).camera.from.x, 2.0);         // eases in
}

TEST(Animation, ObjectKeysApplyAfterTheObjectsOwnTransform) {
  Scene s = two_objects();
  ObjectTrack t;
  t.object = 1;
  ObjectKey a;
  a.frame = 0;
  a.translate = Vec3(0, 0, 0);
  a.rotate = std::vector<AxisAngle>{AxisAngle{Vec3(0, 1, 0), 0}};
  ObjectKey b;
  b.frame = 10;
  b.translate = Vec3(4, 0, 0);
  b.rotate = std::vector<AxisAngle>{AxisAngle{Vec3(0, 1, 0), 180}};
  t.keys = {a, b};
  s.animation.objects = {t};
  const Scene f = scene_at_frame(s, 5);
  EXPECT_EQ(f.objects[0].world_from_object, s.objects[0].world_from_object);
  // Object point (1, 0, 0): scaled by 2 -> (2, 0, 0), turned 90 degrees
  // about y -> (0, 0, -2), moved by (2, 0, 0).
  const Vec3 p = transform_point(f.objects[1].world_from_object, Vec3(1, 0, 0));
  EXPECT_NEAR(p.x, 2.0, 1e-12);
  EXPECT_NEAR(p.y, 0.0, 1e-12);
  EXPECT_NEAR(p.z, -2.0, 1e-12);
}

TEST(Animation, LightKeysMoveLights) {
  Scene s = two_objects();
  LightTrack t;
  t.light = 0;
  t.keys = {LightKey{1, Vec3(0, 0, 0)}, LightKey{3, Vec3(0, 4, 0)}};
  s.animation.lights = {t};
  EXPECT_EQ(scene_at_frame(s, 2).lights[0].position, Vec3(0, 2, 0));
}

TEST(Animation, OrbitTurnsFromAboutAtAroundUp) {
  const Scene s = two_objects();
  const Orbit orbit{90.0, 1, 3};
  EXPECT_EQ(scene_at_frame(s, 1, orbit).camera.from, s.camera.from);  // frame A: unchanged
  const Vec3 mid = scene_at_frame(s, 2, orbit).camera.from;           // 45 degrees
  EXPECT_NEAR(mid.x, 10 * std::sqrt(0.5), 1e-9);
  EXPECT_NEAR(mid.z, 10 * std::sqrt(0.5), 1e-9);
  const Vec3 end = scene_at_frame(s, 3, orbit).camera.from;  // right-handed about +y
  EXPECT_NEAR(end.x, 10.0, 1e-9);
  EXPECT_NEAR(end.z, 0.0, 1e-9);
  EXPECT_EQ(scene_at_frame(s, 3, orbit).camera.up, s.camera.up);
  EXPECT_EQ(orbit_angle(Orbit{30, 5, 5}, 5), 0.0);
}

TEST(Animation, CheckReportsBadTracks) {
  Scene s = two_objects();
  s.source = "anim.json";
  ObjectTrack t;
  t.object = 7;
  ObjectKey a;
  a.frame = 4;
  a.rotate = std::vector<AxisAngle>{AxisAngle{Vec3(0, 1, 0), 0}};
  ObjectKey b;
  b.frame = 2;
  b.rotate = std::vector<AxisAngle>{AxisAngle{Vec3(1, 0, 0), 90}};
  t.keys = {a, b};
  s.animation.objects = {t};
  const std::vector<std::string> problems = check_animation(s);
  auto has = [&](const std::string& text) {
    for (const std::string& p : problems) {
      if (p.find(text) != std::string::npos) return true;
    }
    return false;
  };
  EXPECT_TRUE(has("anim.json: animation.objects[0].object: index 7 out of range"))
      << ::testing::PrintToString(problems);
  EXPECT_TRUE(has("animation.objects[0].keys: keys must be in increasing frame order"));
  EXPECT_TRUE(has("animation.objects[0].keys[1].rotate: must list the same axes"));
  // And never crashes when rendered regardless.
  EXPECT_NO_THROW(scene_at_frame(s, 3));
}

TEST(Animation, ProtoRoundTrip) {
  Animation a;
  a.interpolation = Interpolation::kSmooth;
  CameraKey c;
  c.frame = 2;
  c.at = Vec3(1, 2, 3);
  c.angle = 33;
  a.camera = {c};
  ObjectKey k;
  k.frame = 5;
  k.scale = Vec3(2, 2, 2);
  k.rotate = std::vector<AxisAngle>{AxisAngle{Vec3(0, 0, 1), 45}};
  a.objects = {ObjectTrack{1, {k}}};
  a.lights = {LightTrack{0, {LightKey{9, Vec3(4, 5, 6)}}}};
  v1::Animation p;
  animation_to_proto(a, &p);
  auto back = animation_from_proto(p, "x");
  ASSERT_TRUE(back.ok()) << back.status().message();
  EXPECT_EQ(back->interpolation, Interpolation::kSmooth);
  ASSERT_EQ(back->camera.size(), 1u);
  EXPECT_EQ(*back->camera[0].at, Vec3(1, 2, 3));
  EXPECT_FALSE(back->camera[0].from.has_value());
  EXPECT_EQ(*back->camera[0].angle, 33);
  EXPECT_EQ(*back->objects[0].keys[0].scale, Vec3(2, 2, 2));
  EXPECT_EQ(back->objects[0].keys[0].rotate->at(0).degrees, 45);
  EXPECT_EQ(back->lights[0].keys[0].position, Vec3(4, 5, 6));

  p.mutable_camera(0)->add_from(1.0);  // 1 number where 3 are needed
  auto bad = animation_from_proto(p, "x.json");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("x.json: animation.camera[0].from: expected 3 numbers"),
            std::string::npos)
      << bad.status().message();
}

TEST(Animation, AnimatedExampleScenesLoadAndRoundTrip) {
  for (const char* name : {"glass_and_mirror.json", "spinning_mirror.json"}) {
    auto s = load_scene(std::string(LOCUS_SOURCE_DIR) + "/scenes/anim/" + name);
    ASSERT_TRUE(s.ok()) << s.status().message();
    EXPECT_FALSE(s->animation.empty());
    auto back = scene_from_proto(scene_to_proto(*s), name);
    ASSERT_TRUE(back.ok()) << back.status().message();
    const Scene a = scene_at_frame(*s, 7, Orbit{20, 1, 12});
    const Scene b = scene_at_frame(*back, 7, Orbit{20, 1, 12});
    EXPECT_EQ(a.camera.from, b.camera.from);
    for (size_t i = 0; i < a.objects.size(); ++i) {
      EXPECT_EQ(a.objects[i].world_from_object, b.objects[i].world_from_object)
          << name << " object " << i;
    }
  }
}

TEST(FramePath, ReplacesHashRunsInTheFileName) {
  EXPECT_EQ(frame_path("out/shot_####.png", 7), "out/shot_0007.png");
  EXPECT_EQ(frame_path("shot_#.exr", 123), "shot_123.exr");
  EXPECT_EQ(frame_path("a#b/f_##.png", 3), "a#b/f_03.png");  // only the file name
  EXPECT_EQ(frame_path("still.png", 3), "still.png");
  EXPECT_TRUE(has_frame_field("x/s_##.png"));
  EXPECT_FALSE(has_frame_field("x#/s.png"));
}

}  // namespace
}  // namespace locus
