#include "common/scan/eye_candidates.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace locus {
namespace {

// An interval or outline extent is taken as this much wider (pixels),
// against rounding in the outline crossings.
constexpr double kMargin = 1e-6;

// The pixel columns [a, b] that the x range [lo, hi] meets, within the image.
std::pair<int, int> columns(double lo, double hi, int width) {
  return {clamped_floor(lo - kMargin, 0, width), clamped_floor(hi + kMargin, -1, width - 1)};
}

// Adds primitive p to `prims` unless it is there (a body has several faces).
inline void add_unique(std::vector<int>& prims, int p) {
  if (std::find(prims.begin(), prims.end(), p) == prims.end()) prims.push_back(p);
}

}  // namespace

EyeCandidates::EyeCandidates(const ScanScene& scan, int width, int j0, int j1)
    : scan_(scan), width_(width), j0_(j0), j1_(j1),
      active_(!scan.trace_everything && !scan.any_near_hither),
      rows_(std::max(0, j1 - j0)), row_faces_(rows_.size()) {}

void EyeCandidates::set_line(const std::vector<DepthInterval>& ivs) {
  ivs_ = &ivs;
  line_built_ = false;
}

const std::vector<int>& EyeCandidates::on_line(double x) {
  const std::vector<DepthInterval>& ivs = *ivs_;
  if (!line_built_) {
    line_built_ = true;
    line_.build(width_, static_cast<int>(ivs.size()), [&](int k, auto&& fn) {
      const auto [a, b] = columns(ivs[k].xl, ivs[k].xr, width_);
      for (int i = a; i <= b; ++i) fn(i);
    });
  }
  prims_.clear();
  const int i = clamped_floor(x, 0, width_ - 1);
  line_.visit(i, [&](int k) {
    const DepthInterval& iv = ivs[k];
    if (iv.xl - kMargin <= x && x <= iv.xr + kMargin) add_unique(prims_, scan_.faces[iv.face].prim);
    return false;
  });
  return prims_;
}

const std::vector<int>& EyeCandidates::in_square(double x, double y) {
  const int j = clamped_floor(y, j0_, std::min(j1_, static_cast<int>(scan_.cover.size())) - 1);
  const int i = clamped_floor(x, 0, width_ - 1);
  PixelBuckets& row = rows_[j - j0_];
  std::vector<int>& faces = row_faces_[j - j0_];
  if (row.empty()) {
    // Each face's outline, clipped to the row's band of y: its x extent.
    const double y0 = j - kMargin, y1 = j + 1 + kMargin;
    std::vector<std::pair<int, int>> cols;
    faces.clear();
    for (const int fi : scan_.cover[j]) {
      const std::vector<Vec2>& o = scan_.faces[fi].outline;
      double lo = kInf, hi = -kInf;
      for (size_t k = 0; k < o.size(); ++k) {
        const Vec2 a = o[k], b = o[(k + 1) % o.size()];
        double t0 = 0, t1 = 1;
        const double dy = b.y - a.y;
        if (dy == 0) {
          if (a.y < y0 || a.y > y1) continue;
        } else {
          const double ta = (y0 - a.y) / dy, tb = (y1 - a.y) / dy;
          t0 = std::max(t0, std::min(ta, tb));
          t1 = std::min(t1, std::max(ta, tb));
          if (t0 > t1) continue;
        }
        for (const double t : {t0, t1}) {
          const double xt = a.x + t * (b.x - a.x);
          lo = std::min(lo, xt);
          hi = std::max(hi, xt);
        }
      }
      if (!(lo <= hi) || hi < -kMargin || lo > width_ + kMargin) continue;
      faces.push_back(fi);
      cols.push_back(columns(lo, hi, width_));
    }
    row.build(width_, static_cast<int>(faces.size()), [&](int k, auto&& fn) {
      for (int c = cols[k].first; c <= cols[k].second; ++c) fn(c);
    });
  }
  prims_.clear();
  row.visit(i, [&](int k) {
    add_unique(prims_, scan_.faces[faces[k]].prim);
    return false;
  });
  return prims_;
}

}  // namespace locus
