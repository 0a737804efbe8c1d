// Keyframe animation of a scene (docs/scene-format.md "Animation") and the
// camera orbit of `--orbit DEG`. A frame's scene is a pure function of the
// scene, the frame number and the orbit, so every worker of a farm and the
// in-process renderer build bit-identical frames from the same inputs.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "common/base/math.h"
#include "common/base/status.h"

namespace locus {

struct Scene;
namespace v1 {
class Animation;
}

// A key gives any subset of the camera's animated quantities.
struct CameraKey {
  int frame = 0;
  std::optional<Vec3> from;
  std::optional<Vec3> at;
  std::optional<Vec3> up;
  std::optional<double> angle;
};

struct LightKey {
  int frame = 0;
  Vec3 position{0, 0, 0};
};

struct LightTrack {
  int light = 0;  // index into Scene::lights
  std::vector<LightKey> keys;
};

struct AxisAngle {
  Vec3 axis{0, 1, 0};
  double degrees = 0;
};

// Applied in world space after the object's own transform:
// world_from_object(frame) = translate * rotate[n-1] * ... * rotate[0] * scale
//                            * world_from_object.
struct ObjectKey {
  int frame = 0;
  std::optional<Vec3> translate;
  std::optional<std::vector<AxisAngle>> rotate;
  std::optional<Vec3> scale;
};

struct ObjectTrack {
  int object = 0;  // index into Scene::objects
  std::vector<ObjectKey> keys;
};

enum class Interpolation { kLinear, kSmooth };

struct Animation {
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<CameraKey> camera;
  std::vector<ObjectTrack> objects;
  std::vector<LightTrack> lights;

  bool empty() const { return camera.empty() && objects.empty() && lights.empty(); }
};

// `--orbit DEG`: over frames [first, last] the camera's `from` turns about
// the axis through `at` along `up`, from 0 at `first` to `degrees` at `last`
// (right-handed about `up`).
struct Orbit {
  double degrees = 0;
  int first = 0;
  int last = 0;
};

// The orbit angle at `frame`, in degrees.
double orbit_angle(const Orbit& orbit, int frame);

// The still scene at `frame`: keyframes interpolated, then the orbit applied.
// Quantities that are not animated are copied untouched, so a scene without
// animation and a zero orbit comes back bit-identical. Out-of-range indices
// are skipped (check_animation reports them).
Scene scene_at_frame(Scene scene, int frame, const Orbit& orbit = {});

// Problems of the animation, one "<origin>: animation.<path>: <what>" each:
// indices out of range, keys not in increasing frame order, non-finite
// numbers, zero rotation axes, rotation axes that differ between keys.
std::vector<std::string> check_animation(const Scene& scene);

// The wire/JSON form (proto/scene.proto, message Animation). Structural
// errors (wrong vector lengths) name their JSON path under `origin`.
void animation_to_proto(const Animation& animation, v1::Animation* proto);
Result<Animation> animation_from_proto(const v1::Animation& proto, const std::string& origin);

// Replaces every run of '#' in a frame pattern's file name by the frame
// number, zero-padded to the run's length ("shot_####.png", 7 ->
// "shot_0007.png"). A pattern without '#' is returned unchanged.
std::string frame_path(const std::string& pattern, int frame);

// True when the pattern's file name contains a '#'.
bool has_frame_field(const std::string& pattern);

}  // namespace locus
