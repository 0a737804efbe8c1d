#include "common/scene/animation.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>

#include "common/scene/scene.h"
#include "common/scene/validate.h"
#include "proto/scene.pb.h"

namespace locus {
namespace {

// The keyframed values of one quantity, in frame order.
template <typename T>
struct Samples {
  std::vector<int> frames;
  std::vector<T> values;
};

double mix(double a, double b, double t) { return a + (b - a) * t; }
Vec3 mix(const Vec3& a, const Vec3& b, double t) { return a + (b - a) * t; }

// Held before the first key and after the last; between keys the weight is
// linear in the frame number, or smoothstep-eased.
template <typename T>
std::optional<T> sample(const Samples<T>& s, int frame, Interpolation how) {
  if (s.frames.empty()) return std::nullopt;
  if (frame <= s.frames.front()) return s.values.front();
  if (frame >= s.frames.back()) return s.values.back();
  const size_t k = std::upper_bound(s.frames.begin(), s.frames.end(), frame) - s.frames.begin();
  const int f0 = s.frames[k - 1], f1 = s.frames[k];
  if (f1 <= f0) return s.values[k - 1];
  double t = static_cast<double>(frame - f0) / (f1 - f0);
  if (how == Interpolation::kSmooth) t = t * t * (3.0 - 2.0 * t);
  return mix(s.values[k - 1], s.values[k], t);
}

template <typename Key, typename T, typename Get>
Samples<T> collect(const std::vector<Key>& keys, Get get) {
  Samples<T> s;
  for (const Key& k : keys) {
    if (const auto& v = get(k)) {
      s.frames.push_back(k.frame);
      s.values.push_back(*v);
    }
  }
  return s;
}

// Rotation lists are interpolated angle by angle; the axes are those of the
// earlier key (check_animation requires them equal).
std::optional<std::vector<AxisAngle>> sample_rotation(const std::vector<ObjectKey>& keys, int frame,
                                                      Interpolation how) {
  std::vector<const ObjectKey*> with;
  for (const ObjectKey& k : keys) {
    if (k.rotate) with.push_back(&k);
  }
  if (with.empty()) return std::nullopt;
  if (frame <= with.front()->frame) return *with.front()->rotate;
  if (frame >= with.back()->frame) return *with.back()->rotate;
  size_t k = 1;
  while (k < with.size() && with[k]->frame <= frame) ++k;
  const ObjectKey& a = *with[k - 1];
  const ObjectKey& b = *with[k];
  if (b.frame <= a.frame || a.rotate->size() != b.rotate->size()) return *a.rotate;
  double t = static_cast<double>(frame - a.frame) / (b.frame - a.frame);
  if (how == Interpolation::kSmooth) t = t * t * (3.0 - 2.0 * t);
  std::vector<AxisAngle> out = *a.rotate;
  for (size_t i = 0; i < out.size(); ++i)
    out[i].degrees = mix(a.rotate->at(i).degrees, b.rotate->at(i).degrees, t);
  return out;
}

Mat4 rotation(const Vec3& axis, double degrees) {
  return glm::rotate(Mat4(1.0), glm::radians(degrees), glm::normalize(axis));
}

bool strictly_increasing(const std::vector<int>& frames) {
  for (size_t i = 1; i < frames.size(); ++i) {
    if (frames[i] <= frames[i - 1]) return false;
  }
  return true;
}

std::string origin_of(const Scene& scene) { return scene.source.empty() ? "scene" : scene.source; }

// ---- proto helpers ----

Result<Vec3> vec_from(const google::protobuf::RepeatedField<double>& r, const std::string& path) {
  if (r.size() != 3) {
    return InvalidArgument(path + ": expected 3 numbers [x, y, z], got " +
                           std::to_string(r.size()));
  }
  return Vec3(r[0], r[1], r[2]);
}

void vec_to(const Vec3& v, google::protobuf::RepeatedField<double>* r) {
  r->Clear();
  r->Add(v.x);
  r->Add(v.y);
  r->Add(v.z);
}

}  // namespace

double orbit_angle(const Orbit& orbit, int frame) {
  if (orbit.degrees == 0.0 || orbit.last <= orbit.first) return 0.0;
  return orbit.degrees * static_cast<double>(frame - orbit.first) / (orbit.last - orbit.first);
}

Scene scene_at_frame(Scene s, int frame, const Orbit& orbit) {
  // By value: a caller done with its scene moves it in, and a big mesh is
  // not copied (issue #27, memory per primitive).
  const Animation& a = s.animation;
  const Interpolation how = a.interpolation;

  if (!a.camera.empty()) {
    Camera& c = s.camera;
    auto get = [&](auto field) { return collect<CameraKey, Vec3>(a.camera, field); };
    if (auto v = sample(get([](const CameraKey& k) { return k.from; }), frame, how)) c.from = *v;
    if (auto v = sample(get([](const CameraKey& k) { return k.at; }), frame, how)) c.at = *v;
    if (auto v = sample(get([](const CameraKey& k) { return k.up; }), frame, how)) c.up = *v;
    auto angle = collect<CameraKey, double>(a.camera, [](const CameraKey& k) { return k.angle; });
    if (auto v = sample(angle, frame, how)) c.angle = *v;
  }

  for (const LightTrack& t : a.lights) {
    if (t.light < 0 || static_cast<size_t>(t.light) >= s.lights.size()) continue;
    auto pos = collect<LightKey, Vec3>(
        t.keys, [](const LightKey& k) { return std::optional<Vec3>(k.position); });
    if (auto v = sample(pos, frame, how)) s.lights[t.light].position = *v;
  }

  for (const ObjectTrack& t : a.objects) {
    if (t.object < 0 || static_cast<size_t>(t.object) >= s.objects.size()) continue;
    const auto translate =
        sample(collect<ObjectKey, Vec3>(t.keys, [](const ObjectKey& k) { return k.translate; }),
               frame, how);
    const auto scale = sample(
        collect<ObjectKey, Vec3>(t.keys, [](const ObjectKey& k) { return k.scale; }), frame, how);
    const auto rotate = sample_rotation(t.keys, frame, how);
    if (!translate && !scale && !rotate) continue;
    Mat4 m(1.0);
    if (translate) m = glm::translate(m, *translate);
    if (rotate) {
      for (auto it = rotate->rbegin(); it != rotate->rend(); ++it)
        m = m * rotation(it->axis, it->degrees);
    }
    if (scale) m = glm::scale(m, *scale);
    Object& o = s.objects[t.object];
    o.world_from_object = m * o.world_from_object;
  }

  const double theta = orbit_angle(orbit, frame);
  if (theta != 0.0) {
    Camera& c = s.camera;
    c.from = c.at + transform_vector(rotation(c.up, theta), c.from - c.at);
  }
  return s;
}

std::vector<std::string> check_animation(const Scene& scene) {
  std::vector<std::string> out;
  const Animation& a = scene.animation;
  const std::string origin = origin_of(scene);
  auto report = [&](const std::string& path, const std::string& what) {
    out.push_back(origin + ": animation." + path + ": " + what);
  };
  auto finite = [&](const std::optional<Vec3>& v, const std::string& path) {
    if (v && !is_finite(*v)) report(path, "must be finite, got " + format_vec(*v));
  };

  std::vector<int> frames;
  for (size_t i = 0; i < a.camera.size(); ++i) {
    const CameraKey& k = a.camera[i];
    const std::string p = "camera[" + std::to_string(i) + "]";
    frames.push_back(k.frame);
    finite(k.from, p + ".from");
    finite(k.at, p + ".at");
    finite(k.up, p + ".up");
    if (k.up && is_finite(*k.up) && glm::length(*k.up) == 0.0)
      report(p + ".up", "must not be zero");
    if (k.angle && !(*k.angle > 0.0 && *k.angle < 180.0)) {
      report(p + ".angle", "must be in (0, 180) degrees, got " + format_number(*k.angle));
    }
  }
  if (!strictly_increasing(frames))
    report("camera", "keys must be in increasing frame order, each frame once");

  for (size_t i = 0; i < a.lights.size(); ++i) {
    const LightTrack& t = a.lights[i];
    const std::string p = "lights[" + std::to_string(i) + "]";
    if (t.light < 0 || static_cast<size_t>(t.light) >= scene.lights.size()) {
      report(p + ".light", "index " + std::to_string(t.light) + " out of range, the scene has " +
                               std::to_string(scene.lights.size()) + " lights");
    }
    frames.clear();
    for (size_t j = 0; j < t.keys.size(); ++j) {
      frames.push_back(t.keys[j].frame);
      finite(t.keys[j].position, p + ".keys[" + std::to_string(j) + "].position");
    }
    if (!strictly_increasing(frames))
      report(p + ".keys", "keys must be in increasing frame order, each frame once");
  }

  for (size_t i = 0; i < a.objects.size(); ++i) {
    const ObjectTrack& t = a.objects[i];
    const std::string p = "objects[" + std::to_string(i) + "]";
    if (t.object < 0 || static_cast<size_t>(t.object) >= scene.objects.size()) {
      report(p + ".object", "index " + std::to_string(t.object) + " out of range, the scene has " +
                                std::to_string(scene.objects.size()) + " objects");
    }
    frames.clear();
    const std::vector<AxisAngle>* first_rotate = nullptr;
    for (size_t j = 0; j < t.keys.size(); ++j) {
      const ObjectKey& k = t.keys[j];
      const std::string kp = p + ".keys[" + std::to_string(j) + "]";
      frames.push_back(k.frame);
      finite(k.translate, kp + ".translate");
      finite(k.scale, kp + ".scale");
      if (k.scale && is_finite(*k.scale) && k.scale->x * k.scale->y * k.scale->z == 0.0) {
        report(kp + ".scale", "must not be zero in any axis, got " + format_vec(*k.scale));
      }
      if (!k.rotate) continue;
      for (size_t r = 0; r < k.rotate->size(); ++r) {
        const AxisAngle& aa = (*k.rotate)[r];
        const std::string rp = kp + ".rotate[" + std::to_string(r) + "]";
        if (!is_finite(aa.axis) || glm::length(aa.axis) == 0.0) {
          report(rp + ".axis", "must be a finite non-zero vector, got " + format_vec(aa.axis));
        }
        if (!is_finite(aa.degrees)) report(rp + ".degrees", "must be finite");
      }
      if (!first_rotate) {
        first_rotate = &*k.rotate;
      } else {
        bool same = first_rotate->size() == k.rotate->size();
        for (size_t r = 0; same && r < k.rotate->size(); ++r)
          same = (*first_rotate)[r].axis == (*k.rotate)[r].axis;
        if (!same) {
          report(kp + ".rotate",
                 "must list the same axes in the same order as the track's first rotate; "
                 "only the degrees are interpolated");
        }
      }
    }
    if (!strictly_increasing(frames))
      report(p + ".keys", "keys must be in increasing frame order, each frame once");
  }
  return out;
}

void animation_to_proto(const Animation& a, v1::Animation* p) {
  p->Clear();
  p->set_interpolation(a.interpolation == Interpolation::kSmooth ? v1::Animation::SMOOTH
                                                                 : v1::Animation::LINEAR);
  for (const CameraKey& k : a.camera) {
    v1::CameraKey* pk = p->add_camera();
    pk->set_frame(k.frame);
    if (k.from) vec_to(*k.from, pk->mutable_from());
    if (k.at) vec_to(*k.at, pk->mutable_at());
    if (k.up) vec_to(*k.up, pk->mutable_up());
    if (k.angle) pk->set_angle(*k.angle);
  }
  for (const ObjectTrack& t : a.objects) {
    v1::ObjectTrack* pt = p->add_objects();
    pt->set_object(t.object);
    for (const ObjectKey& k : t.keys) {
      v1::ObjectKey* pk = pt->add_keys();
      pk->set_frame(k.frame);
      if (k.translate) vec_to(*k.translate, pk->mutable_translate());
      if (k.rotate) {
        for (const AxisAngle& r : *k.rotate) {
          v1::Rotation* pr = pk->add_rotate();
          vec_to(r.axis, pr->mutable_axis());
          pr->set_degrees(r.degrees);
        }
      }
      if (k.scale) vec_to(*k.scale, pk->mutable_scale());
    }
  }
  for (const LightTrack& t : a.lights) {
    v1::LightTrack* pt = p->add_lights();
    pt->set_light(t.light);
    for (const LightKey& k : t.keys) {
      v1::LightKey* pk = pt->add_keys();
      pk->set_frame(k.frame);
      vec_to(k.position, pk->mutable_position());
    }
  }
}

Result<Animation> animation_from_proto(const v1::Animation& p, const std::string& origin) {
  Animation a;
  std::vector<std::string> problems;
  const std::string base = origin + ": animation.";
  auto vec = [&](const google::protobuf::RepeatedField<double>& r,
                 const std::string& path) -> std::optional<Vec3> {
    if (r.empty()) return std::nullopt;
    auto v = vec_from(r, base + path);
    if (!v.ok()) {
      problems.push_back(v.status().message());
      return std::nullopt;
    }
    return *v;
  };
  a.interpolation =
      p.interpolation() == v1::Animation::SMOOTH ? Interpolation::kSmooth : Interpolation::kLinear;
  for (int i = 0; i < p.camera_size(); ++i) {
    const v1::CameraKey& pk = p.camera(i);
    const std::string path = "camera[" + std::to_string(i) + "].";
    CameraKey k;
    k.frame = pk.frame();
    k.from = vec(pk.from(), path + "from");
    k.at = vec(pk.at(), path + "at");
    k.up = vec(pk.up(), path + "up");
    if (pk.has_angle()) k.angle = pk.angle();
    a.camera.push_back(k);
  }
  for (int i = 0; i < p.objects_size(); ++i) {
    const v1::ObjectTrack& pt = p.objects(i);
    ObjectTrack t;
    t.object = pt.object();
    for (int j = 0; j < pt.keys_size(); ++j) {
      const v1::ObjectKey& pk = pt.keys(j);
      const std::string path =
          "objects[" + std::to_string(i) + "].keys[" + std::to_string(j) + "].";
      ObjectKey k;
      k.frame = pk.frame();
      k.translate = vec(pk.translate(), path + "translate");
      if (pk.scale_size() == 1) {
        k.scale = Vec3(pk.scale(0));
      } else if (pk.scale_size() > 0) {
        k.scale = vec(pk.scale(), path + "scale");
      }
      if (pk.rotate_size() > 0) {
        std::vector<AxisAngle> rs;
        for (int r = 0; r < pk.rotate_size(); ++r) {
          AxisAngle aa;
          if (auto axis = vec(pk.rotate(r).axis(), path + "rotate[" + std::to_string(r) + "].axis"))
            aa.axis = *axis;
          aa.degrees = pk.rotate(r).degrees();
          rs.push_back(aa);
        }
        k.rotate = std::move(rs);
      }
      t.keys.push_back(std::move(k));
    }
    a.objects.push_back(std::move(t));
  }
  for (int i = 0; i < p.lights_size(); ++i) {
    const v1::LightTrack& pt = p.lights(i);
    LightTrack t;
    t.light = pt.light();
    for (int j = 0; j < pt.keys_size(); ++j) {
      LightKey k;
      k.frame = pt.keys(j).frame();
      const std::string path =
          "lights[" + std::to_string(i) + "].keys[" + std::to_string(j) + "].position";
      if (pt.keys(j).position().empty()) {
        problems.push_back(base + path + ": required, 3 numbers [x, y, z]");
      } else if (auto v = vec(pt.keys(j).position(), path)) {
        k.position = *v;
      }
      t.keys.push_back(k);
    }
    a.lights.push_back(std::move(t));
  }
  if (!problems.empty()) return problems_status(problems);
  return a;
}

std::string frame_path(const std::string& pattern, int frame) {
  const std::filesystem::path p(pattern);
  std::string name = p.filename().string();
  std::string out;
  for (size_t i = 0; i < name.size();) {
    if (name[i] != '#') {
      out += name[i++];
      continue;
    }
    size_t n = 0;
    while (i + n < name.size() && name[i + n] == '#') ++n;
    std::string digits = std::to_string(frame);
    if (digits.size() < n) digits.insert(0, n - digits.size(), '0');
    out += digits;
    i += n;
  }
  return (p.parent_path() / out).string();
}

bool has_frame_field(const std::string& pattern) {
  return std::filesystem::path(pattern).filename().string().find('#') != std::string::npos;
}

}  // namespace locus
