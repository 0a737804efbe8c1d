#include "common/scan/local.h"

#include <optional>

#include "common/scan/scanline.h"
#include "common/scan/span_shadows.h"
#include "common/trace/raytrace.h"

namespace locus {

void local_rows(const PreparedScene& ps, const RenderParams& params, const Band& band, int y,
                Image& out, Stats& stats, CostBuffer* cost) {
  CostMeter meter(cost, stats);
  meter.set_row(y);
  const CameraFrame& cam = ps.camera;
  const ScanScene& scan = *ps.scan;
  Tracer tracer(ps, stats);
  const RowVisibility vis = visible_faces(scan, cam, cam.from, y);
  stats.spans_total += vis.spans;
  (void)params;
  // The shadows of each span come from the shadow volumes before shading
  // (paper §3.2 step 2); IV narrows the volumes by the boxes and the face's
  // candidate list, II and III meet every occluder's volume.
  std::optional<SpanShadows> shadows;
  if (ps.volumes) shadows.emplace(ps, y + 0.5, stats);
  meter.charge_run(0, cam.width);  // the row's set-up, for all its pixels

  bool prev_traced = false;
  int prev_face = -2;
  for (int x = 0; x < cam.width; ++x) {
    const int fi = vis.face[x];
    if (shadows && fi >= 0 && (x == 0 || vis.face[x - 1] != fi)) {
      int x1 = x + 1;
      while (x1 < cam.width && vis.face[x1] == fi) ++x1;
      shadows->begin_span(fi, x, x1);
      meter.charge_run(x, x1);  // the span's shadow volumes, for all its pixels
    }
    const Ray ray{cam.from, cam.direction(x + 0.5, y + 0.5)};
    Color c = ps.scene.background;
    bool traced = false, span = false;
    if (scan.trace_everything || (fi >= 0 && (scan.faces[fi].curved || scan.faces[fi].near_hither))) {
      // Inside a curved body's bounding polyhedron: the ray finds the true
      // surface, or whatever lies behind it (paper §3.2).
      ++stats.rays_eye;
      c = tracer.trace(ray, cam.hither, 1, 1.0, nullptr);
      traced = span = true;
    } else if (fi >= 0) {
      // The visible face is known: its hit point is a ray-plane intersection
      // with that one surface, no eye-ray search.
      const ScanFace& f = scan.faces[fi];
      ++stats.tests_ray_object;
      const auto hit = hit_on_face(ps, f, ray);
      if (!hit) {
        // The sample grazes the face's edge, or the surface lies inside
        // hither's sphere: let a ray decide.
        ++stats.rays_eye;
        c = tracer.trace(ray, cam.hither, 1, 1.0, nullptr);
        traced = true;
      } else {
        const Material& m = ps.material_of(hit->leaf);
        traced = span = m.ks > 0 || m.t > 0;
        if (shadows) shadows->set_pixel(x);
        c = tracer.shade(ray, SurfaceHit{hit->t, f.prim, *hit}, 1, 1.0, nullptr,
                         shadows ? &*shadows : nullptr);
      }
    }
    meter.charge(x);
    if (traced) {
      meter.mark_traced(x, span);
      ++stats.pixels_ray_traced;
      if (!prev_traced || fi != prev_face) ++stats.spans_ray_traced;
    }
    prev_traced = traced;
    prev_face = fi;
    store_pixel(out, band, x, y, c);
  }
  stats.pixels_total += cam.width;
}

}  // namespace locus
