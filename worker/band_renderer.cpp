#include "worker/band_renderer.h"

#include <algorithm>
#include <cstdio>

#include "common/farm/paths.h"
#include "common/prepare/prepared.h"
#include "common/scene/animation.h"
#include "common/scene/scene_io.h"
#include "proto/scene.pb.h"

namespace locus::farm {

BandRenderer::BandRenderer(int threads, std::string mesh_root, size_t max_scenes,
                           size_t max_prepared)
    : threads_(threads),
      mesh_root_(std::move(mesh_root)),
      max_scenes_(std::max<size_t>(1, max_scenes)),
      max_prepared_(std::max<size_t>(1, max_prepared)) {}

Status BandRenderer::add_scene(const std::string& hash, const v1::Scene& proto,
                               const std::string& name) {
  if (scenes_.count(hash)) return Status::Ok();
  // The scene came over the network: it reads no file outside the root.
  Result<Scene> scene = scene_from_wire(proto, mesh_root_, name);
  if (!scene.ok()) return scene.status();
  while (scenes_.size() >= max_scenes_) {
    scenes_.erase(scene_order_.front());
    scene_order_.pop_front();
  }
  auto held = std::make_shared<const Scene>(std::move(*scene));
  auto geometry = std::make_unique<AnimationGeometry>(*held);
  scenes_.emplace(hash, Held{std::move(held), std::move(geometry)});
  scene_order_.push_back(hash);
  return Status::Ok();
}

Status BandRenderer::add_scene_bytes(const std::string& hash, const std::string& bytes,
                                     const std::string& name) {
  if (scenes_.count(hash)) return Status::Ok();
  v1::Scene scene;
  if (!scene.ParseFromString(bytes)) {
    return InvalidArgument(name + ": " + std::to_string(bytes.size()) +
                           " bytes that do not parse as a scene");
  }
  return add_scene(hash, scene, name);
}

Result<BandOutput> BandRenderer::render(const BandLease& t, const std::atomic<bool>* abandon) {
  auto it = scenes_.find(t.scene_hash);
  if (it == scenes_.end()) return FailedPrecondition("scene " + t.scene_hash + " is not held");
  Result<RenderParams> params = to_render_params(t.render, threads_);
  if (!params.ok()) return params.status();
  if (t.width < 1 || t.height < 1 || t.width > kMaxResolution || t.height > kMaxResolution ||
      t.y0 < 0 || t.y1 <= t.y0 || t.y1 > t.height) {
    return InvalidArgument("band rows [" + std::to_string(t.y0) + ", " + std::to_string(t.y1) +
                           ") do not fit a " + std::to_string(t.width) + "x" +
                           std::to_string(t.height) + " frame");
  }
  // Everything prepare_scene depends on: the bands of one frame share it.
  char key[512];
  std::snprintf(key, sizeof key, "%s|%d|%dx%d|%.17g|%d-%d|%s|%s|%d|%d|%.17g", t.scene_hash.c_str(),
                t.frame, t.width, t.height, t.orbit_degrees, t.frame_first, t.frame_last,
                t.render.method.c_str(), t.render.boxes.c_str(), params->spp, params->aa,
                params->tess_tol);
  std::shared_ptr<const PreparedScene> prepared;
  double prepare_seconds = 0;
  bool fresh = false;
  for (auto p = prepared_.begin(); p != prepared_.end(); ++p) {
    if (p->key == key) {
      prepared = p->scene;
      prepared_.splice(prepared_.begin(), prepared_, p);
      break;
    }
  }
  if (!prepared) {
    const auto start = SteadyClock::now();
    const Scene& source = *it->second.scene;
    const Camera view = frame_camera(source, t.width, t.height, t.frame, t.frame_first,
                                     t.frame_last, t.orbit_degrees);
    bool reused = false;
    auto r = it->second.geometry->prepare(
        view,
        [&] {
          return frame_scene(source, t.width, t.height, t.frame, t.frame_first, t.frame_last,
                             t.orbit_degrees);
        },
        *params, &reused);
    if (!r.ok()) return r.status();
    prepared = *r;
    ++prepares_;
    if (reused) ++geometry_reuses_;
    fresh = true;
    prepare_seconds = std::chrono::duration<double>(SteadyClock::now() - start).count();
    prepared_.push_front(Prepared{key, t.scene_hash, prepared});
    while (prepared_.size() > max_prepared_) prepared_.pop_back();
    // A geometry is kept for the scenes of the frames kept, no more: a
    // worker's memory stays that of its last frames.
    for (auto& [hash, held] : scenes_) {
      const bool in_use = std::any_of(prepared_.begin(), prepared_.end(),
                                      [&](const Prepared& p) { return p.scene_hash == hash; });
      if (!in_use) held.geometry->release();
    }
  }
  // A job with cost maps: the band's work per pixel too (docs/cost-map.md).
  CostBuffer cost;
  BandResult band =
      render_band(*prepared, Band{t.y0, t.y1}, *params, abandon, t.cost_map ? &cost : nullptr);
  if (band.cancelled) {
    return Status(Code::kCancelled, "band abandoned: its lease was revoked or handed back");
  }
  BandOutput out;
  out.rgb = std::move(band.pixels.rgb);
  out.stats = band.stats;
  out.stats.seconds_prepare = prepare_seconds;
  // Like prepare time, tessellation is counted by the band that prepared.
  out.stats.seconds_tessellate = fresh ? prepared->seconds_tessellate : 0.0;
  if (t.cost_map) {
    auto bytes = encode_band_cost(cost);
    if (!bytes.ok()) return bytes.status();
    out.cost = std::move(*bytes);
  }
  // Only what the job's output file keeps travels (band_codec.h).
  if (t.encoding != BandEncoding::kFloat32) {
    auto encoded = encode_band(t.encoding, t.width, t.y1 - t.y0, out.rgb, t.y0, t.height);
    if (!encoded.ok()) return encoded.status();
    out.encoded = std::move(*encoded);
    out.rgb = {};
  }
  return out;
}

}  // namespace locus::farm
