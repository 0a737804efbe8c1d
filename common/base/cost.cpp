#include "common/base/cost.h"

#include <algorithm>

#include "common/base/math.h"

namespace locus {

void CostBuffer::reset(int w, int first, int last) {
  width = w;
  y0 = first;
  y1 = last;
  pixels.assign(static_cast<size_t>(w) * std::max(0, last - first), PixelCost{});
}

Stats CostBuffer::totals() const {
  Stats s;
  for (const PixelCost& p : pixels) {
    s.rays_eye += p.rays_eye;
    s.rays_reflected += p.rays_reflected;
    s.rays_refracted += p.rays_refracted;
    s.rays_shadow += p.rays_shadow;
    s.tests_shadow_volume += p.tests_shadow_volume;
    s.pixels_ray_traced += p.traced ? 1 : 0;
  }
  return s;
}

void CostMeter::charge_run_(double a, double b) {
  const int x0 = clamped_floor(a, 0, buf_->width - 1);
  const int x1 = std::max(x0 + 1, clamped_ceil(b, 0, buf_->width));
  const Counts now = Counts::of(stats_);
  const uint64_t k = static_cast<uint64_t>(x1 - x0);
  for (int c = 0; c < 5; ++c) {
    const uint64_t d = now.n[c] - last_.n[c];
    if (d == 0) continue;
    // Evenly, the remainder one each to the run's first pixels: the pixels'
    // counts still sum to the Stats' totals.
    const uint64_t each = d / k, extra = d % k;
    for (int x = x0; x < x1; ++x) {
      PixelCost& p = buf_->at(x, row_);
      uint32_t* field[5] = {&p.rays_eye, &p.rays_reflected, &p.rays_refracted, &p.rays_shadow,
                            &p.tests_shadow_volume};
      *field[c] += static_cast<uint32_t>(each + (static_cast<uint64_t>(x - x0) < extra ? 1 : 0));
    }
  }
  last_ = now;
}

}  // namespace locus
