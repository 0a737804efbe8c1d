#include "common/render.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>
#include <utility>

#include "common/base/cpu_time.h"
#include "common/base/log.h"
#include "common/base/parallel.h"
#include "common/prepare/prepared.h"
#include "common/prepare/shadow_volume.h"
#include "common/prepare/tessellate.h"
#include "common/scan/local.h"
#include "common/scan/multiscan.h"
#include "common/scene/validate.h"
#include "common/trace/raytrace.h"

namespace locus {

namespace {
// Rows per unit of multi-scanning work: one sub-scanline in 8n is computed
// twice (at each chunk's first row), and threads still share a band.
constexpr int kMultiscanChunk = 8;
}  // namespace

namespace {
std::function<void(int)>& row_hook() {
  static std::function<void(int)> hook;
  return hook;
}
}  // namespace

void set_row_hook_for_test(std::function<void(int row)> hook) { row_hook() = std::move(hook); }

BandResult render_band(const PreparedScene& ps, const Band& band, const RenderParams& params,
                       const std::atomic<bool>* cancel, CostBuffer* cost) {
  const auto start = std::chrono::steady_clock::now();
  const int y0 = std::clamp(band.y0, 0, ps.camera.height);
  const int y1 = std::clamp(band.y1, y0, ps.camera.height);
  BandResult result;
  result.pixels = Image(ps.camera.width, y1 - y0);
  if (cost) cost->reset(ps.camera.width, y0, y1);
  const int threads = std::max(1, std::min(render_threads(params), y1 - y0));
  // Each thread counts into its own cache lines: a counter bumped per ray
  // must not share a line with another thread's.
  struct alignas(64) ThreadStats {
    Stats s;
  };
  std::vector<ThreadStats> stats(threads);
  std::atomic<int> next{y0};
  std::vector<double> cpu(threads, 0.0);
  const std::function<void(int)>& hook = row_hook();
  std::atomic<bool> stopped{false};
  // Before each row: the test hook, then the cancellation flag.
  auto row_may_start = [&](int row) {
    if (hook) hook(row);
    if (cancel && cancel->load(std::memory_order_relaxed)) {
      stopped.store(true, std::memory_order_relaxed);
      return false;
    }
    return true;
  };
  auto work = [&](int id) {
    struct CpuClock {
      double& out;
      double start = thread_cpu_seconds();
      ~CpuClock() { out = thread_cpu_seconds() - start; }
    } clock{cpu[id]};
    if (ps.scan && params.aa > 0) {
      // Multi-scanning: chunks of rows, so that inside a chunk each
      // boundary sub-scanline is computed once (common/scan/multiscan.h).
      for (int y = next.fetch_add(kMultiscanChunk); y < y1; y = next.fetch_add(kMultiscanChunk)) {
        multiscan_rows(ps, params, Band{y0, y1}, y, std::min(y1, y + kMultiscanChunk),
                       result.pixels, stats[id].s, row_may_start, cost);
        if (stopped.load(std::memory_order_relaxed)) return;
      }
      return;
    }
    for (int y = next++; y < y1; y = next++) {
      if (!row_may_start(y)) return;
      if (ps.scan) {
        local_rows(ps, params, Band{y0, y1}, y, result.pixels, stats[id].s, cost);
      } else {
        raytrace_rows(ps, params, Band{y0, y1}, y, result.pixels, stats[id].s, cost);
      }
    }
  };
  std::vector<std::thread> pool;
  // The pool logs under the caller's band ids (its lines go to the band's log).
  const BandLogIds log_ids = current_band_log_ids();
  for (int i = 1; i < threads; ++i) {
    pool.emplace_back([&, i] {
      BandLogScope scope(log_ids);
      work(i);
    });
  }
  work(0);
  for (auto& t : pool) t.join();
  result.cancelled = stopped.load();
  for (const ThreadStats& t : stats) result.stats += t.s;
  for (const double c : cpu) result.stats.seconds_render_cpu += c;
  result.stats.geometry_triangles = ps.prims.triangles.size();
  result.stats.visibility = ps.scan && !ps.by_rays ? "scanline" : "rays";
  result.stats.shadow_method = !ps.volumes                  ? "rays"
                               : ps.points_search_volumes() ? "volumes"
                                                            : "volumes+rays";
  result.stats.seconds_render =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

namespace {

// The frame `prepared` (prepared since `start`) rendered whole.
Result<BandResult> render_prepared(const Result<std::shared_ptr<const PreparedScene>>& prepared,
                                   std::chrono::steady_clock::time_point start,
                                   const RenderParams& params, CostBuffer* cost) {
  if (!prepared.ok()) return prepared.status();
  const double prep =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  BandResult r =
      render_band(**prepared, Band{0, (*prepared)->camera.height}, params, nullptr, cost);
  r.stats.seconds_prepare = prep;
  r.stats.seconds_tessellate = (*prepared)->seconds_tessellate;
  return r;
}

}  // namespace

Result<BandResult> render_image(Scene scene, const RenderParams& params, CostBuffer* cost) {
  const auto start = std::chrono::steady_clock::now();
  return render_prepared(prepare_scene(std::move(scene), params), start, params, cost);
}

Result<BandResult> render_frame(AnimationGeometry& geometry, const Camera& view,
                                FunctionRef<Scene()> frame, const RenderParams& params,
                                CostBuffer* cost) {
  const auto start = std::chrono::steady_clock::now();
  return render_prepared(geometry.prepare(view, frame, params), start, params, cost);
}

}  // namespace locus
