// The cost map (issue #27 item 5; docs/cost-map.md): a picture of where a
// render's work went, the paper's Fig. 1 for any scene. Each pixel's work
// (rays of every kind plus shadow-volume tests, cost.h) in a false-colour
// scale, log10(1 + work), dark to bright; the spans ray traced by the local
// method (paper §3.2) outlined in cyan; a legend strip over the bottom rows:
// the scale with numbered ticks in a small built-in bitmap font, the
// outline's swatch and what the measure counts.
#pragma once

#include <cstdint>
#include <string>

#include "common/base/cost.h"
#include "common/base/image.h"
#include "common/base/math.h"

namespace locus {

// The outline of ray-traced spans; no colour of the ramp comes near it.
inline const Color kTracedOutline{0.0, 1.0, 1.0};

// The ramp at t in [0, 1] (clamped): black, purple, red, orange, pale
// yellow, its lightness rising throughout (control points after matplotlib's
// "inferno"), as display values (sRGB-encoded).
Color cost_ramp(double t);

// The scale's top for a largest work `max_work`: the least 1, 2 or 5 times a
// power of ten that is at least it (at least 1).
uint64_t cost_scale_top(uint64_t max_work);

// The picture of `cost`, as large as it (display values: write it with
// write_image(..., for_display = true)). `top`: the work at the ramp's top;
// 0 = cost_scale_top of the buffer's largest. The legend is drawn only when
// the picture is at least kCostLegendMinWidth wide and four legends high.
inline constexpr int kCostLegendMinWidth = 96;
Image cost_map_image(const CostBuffer& cost, uint64_t top = 0);

// Text in the legend's font (3 x 5 pixels a glyph, each drawn as a square
// of `scale` pixels, 4 * scale apart): upper-case letters, digits and
// " +-.:/()"; any other character is drawn as a space. Exposed for tests.
void draw_cost_text(Image& image, int x, int y, int scale, const std::string& text,
                    const Color& colour);
// How wide draw_cost_text draws `text`, in pixels.
int cost_text_width(const std::string& text, int scale);

}  // namespace locus
