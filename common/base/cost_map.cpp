#include "common/base/cost_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace locus {
namespace {

// The ramp's control points, evenly spaced in t: matplotlib's "inferno" at
// t = 0, 1/4, 1/2, 3/4, 1 (a perceptually uniform map whose lightness rises
// monotonically), interpolated linearly between them.
constexpr std::array<std::array<double, 3>, 5> kRamp = {{
    {0.001, 0.000, 0.014},
    {0.341, 0.062, 0.429},
    {0.735, 0.216, 0.330},
    {0.978, 0.557, 0.035},
    {0.988, 0.998, 0.645},
}};

// The legend's colours: its strip, its text and tick marks.
const Color kStrip{0.08, 0.08, 0.08};
const Color kInk{0.95, 0.95, 0.95};

// A 3 x 5 glyph, row by row from the top, '#' set.
struct Glyph {
  char c;
  const char* rows;  // 15 characters
};
constexpr Glyph kFont[] = {
    {'0', "####.##.##.####"}, {'1', ".#.##..#..#.###"}, {'2', "###..#####..###"},
    {'3', "###..####..####"}, {'4', "#.##.####..#..#"}, {'5', "####..###..####"},
    {'6', "####..####.####"}, {'7', "###..#..#.#..#."}, {'8', "####.#####.####"},
    {'9', "####.####..####"}, {'A', ".#.#.#####.##.#"}, {'B', "##.#.###.#.###."},
    {'C', ".###..#..#...##"}, {'D', "##.#.##.##.###."}, {'E', "####..##.#..###"},
    {'F', "####..##.#..#.."}, {'G', ".###..#.##.#.##"}, {'H', "#.##.#####.##.#"},
    {'I', "###.#..#..#.###"}, {'J', "..#..#..##.#.#."}, {'K', "#.##.###.#.##.#"},
    {'L', "#..#..#..#..###"}, {'M', "#.########.##.#"}, {'N', "##.#.##.##.##.#"},
    {'O', ".#.#.##.##.#.#."}, {'P', "##.#.###.#..#.."}, {'Q', ".#.#.##.###..##"},
    {'R', "##.#.###.#.##.#"}, {'S', ".###...#...###."}, {'T', "###.#..#..#..#."},
    {'U', "#.##.##.##.####"}, {'V', "#.##.##.##.#.#."}, {'W', "#.##.########.#"},
    {'X', "#.##.#.#.#.##.#"}, {'Y', "#.##.#.#..#..#."}, {'Z', "###..#.#.#..###"},
    {'+', "....#.###.#...."}, {'-', "......###......"}, {'.', ".............#."},
    {':', "....#.....#...."}, {'/', "..#..#.#.#..#.."}, {'(', ".#.#..#..#...#."},
    {')', ".#...#..#..#.#."},
};

const char* glyph_rows(char c) {
  for (const Glyph& g : kFont) {
    if (g.c == c) return g.rows;
  }
  return nullptr;  // a space
}

void put(Image& img, int x, int y, const Color& c) {
  if (x < 0 || y < 0 || x >= img.width || y >= img.height) return;
  float* p = img.pixel(x, y);
  p[0] = static_cast<float>(c.x);
  p[1] = static_cast<float>(c.y);
  p[2] = static_cast<float>(c.z);
}

void fill(Image& img, int x0, int y0, int x1, int y1, const Color& c) {
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) put(img, x, y, c);
  }
}

// A tick's number: 0, 1, 2, 5, 10, ..., 1k, 20k, 5M.
std::string tick_label(uint64_t v) {
  const char* suffix = "";
  if (v >= 1000000 && v % 1000000 == 0) {
    v /= 1000000;
    suffix = "M";
  } else if (v >= 1000 && v % 1000 == 0) {
    v /= 1000;
    suffix = "K";
  }
  std::string s = std::to_string(v);
  s.append(suffix);
  return s;
}

// The legend over the bottom rows of `img` (docs/cost-map.md "The legend"):
// the ramp as a bar from 0 to `top`, tick marks at 0, 1, 10, 100, ... and
// `top` with their numbers under them, and a caption line: what is counted
// on the left, the outline's swatch on the right.
void draw_legend(Image& img, uint64_t top) {
  const int w = img.width, h = img.height;
  const int s = std::max(1, w / 256);  // the font's pixel, and the unit of the layout
  const int m = 2 * s;
  const int text_h = 5 * s;
  const int strip = m + 4 * s + 2 * s + s + text_h + 2 * s + text_h + m;
  if (w < kCostLegendMinWidth || h < 4 * strip) return;
  const int y0 = h - strip;
  fill(img, 0, y0, w, h, kStrip);
  // The bar: x in [bx0, bx1) holds work expm1(t log1p(top)), t its place.
  const int bx0 = m, bx1 = w - m, bar_y = y0 + m;
  const double span = std::log1p(static_cast<double>(top));
  for (int x = bx0; x < bx1; ++x) {
    const Color c = cost_ramp((x - bx0 + 0.5) / (bx1 - bx0));
    fill(img, x, bar_y, x + 1, bar_y + 4 * s, c);
  }
  auto place = [&](uint64_t v) {
    const double t = std::log1p(static_cast<double>(v)) / span;
    return bx0 + static_cast<int>(std::lround(t * (bx1 - bx0 - s)));
  };
  const int tick_y = bar_y + 4 * s, label_y = tick_y + 3 * s;
  // The top's number, right-aligned under its tick; then 0, 1, 10, ... left
  // to right, each where it overlaps neither its left neighbour nor the top's.
  const std::string top_text = tick_label(top);
  const int top_x = place(top);
  const int top_left = std::min(w - m, top_x + s) - cost_text_width(top_text, s);
  fill(img, top_x, tick_y, top_x + s, tick_y + 2 * s, kInk);
  draw_cost_text(img, top_left, label_y, s, top_text, kInk);
  int free_from = 0;
  for (uint64_t v = 0; v < top; v = v == 0 ? 1 : v * 10) {
    const int x = place(v);
    const std::string text = tick_label(v);
    const int tw = cost_text_width(text, s);
    const int left = std::max(0, x - tw / 2);
    fill(img, x, tick_y, x + s, tick_y + 2 * s, kInk);
    if (left >= free_from && left + tw + 2 * s <= top_left) {
      draw_cost_text(img, left, label_y, s, text, kInk);
      free_from = left + tw + 2 * s;
    }
  }
  // The caption: the outline's swatch and name at the right; what is
  // counted at the left, the longest wording that fits.
  const int cap_y = label_y + text_h + 2 * s;
  const std::string traced = "RAY TRACED";
  const int key_w = 5 * s + 2 * s + cost_text_width(traced, s);
  const int key_x = w - m - key_w;
  fill(img, key_x, cap_y, key_x + 5 * s, cap_y + 5 * s, kTracedOutline);
  draw_cost_text(img, key_x + 7 * s, cap_y, s, traced, kInk);
  for (const char* caption : {"RAYS + SHADOW-VOLUME TESTS PER PIXEL (LOG)",
                              "RAYS + VOLUME TESTS PER PIXEL", "RAYS+TESTS/PIXEL", "WORK"}) {
    if (m + cost_text_width(caption, s) + 4 * s <= key_x) {
      draw_cost_text(img, m, cap_y, s, caption, kInk);
      break;
    }
  }
}

}  // namespace

Color cost_ramp(double t) {
  t = std::clamp(t, 0.0, 1.0) * (kRamp.size() - 1);
  const size_t i = std::min(kRamp.size() - 2, static_cast<size_t>(t));
  const double f = t - static_cast<double>(i);
  const auto& a = kRamp[i];
  const auto& b = kRamp[i + 1];
  return Color(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]));
}

uint64_t cost_scale_top(uint64_t max_work) {
  for (uint64_t decade = 1;; decade *= 10) {
    for (const uint64_t k : {1, 2, 5}) {
      if (k * decade >= max_work) return k * decade;
    }
    if (decade > UINT64_MAX / 100) return max_work;
  }
}

int cost_text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : (4 * static_cast<int>(text.size()) - 1) * scale;
}

void draw_cost_text(Image& image, int x, int y, int scale, const std::string& text,
                    const Color& colour) {
  for (size_t k = 0; k < text.size(); ++k) {
    const char* rows = glyph_rows(text[k]);
    if (!rows) continue;
    const int gx = x + static_cast<int>(k) * 4 * scale;
    for (int r = 0; r < 5; ++r) {
      for (int c = 0; c < 3; ++c) {
        if (rows[r * 3 + c] != '#') continue;
        fill(image, gx + c * scale, y + r * scale, gx + (c + 1) * scale, y + (r + 1) * scale,
             colour);
      }
    }
  }
}

Image cost_map_image(const CostBuffer& cost, uint64_t top) {
  const int w = cost.width, h = cost.height();
  Image img(w, h);
  uint64_t largest = 0;
  for (const PixelCost& p : cost.pixels) largest = std::max(largest, p.work());
  if (top == 0) top = cost_scale_top(largest);
  const double span = std::log1p(static_cast<double>(top));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double work = static_cast<double>(cost.at(x, cost.y0 + y).work());
      put(img, x, y, cost_ramp(std::log1p(work) / span));
    }
  }
  // The outline: pixels of ray-traced spans with a 4-neighbour in the image
  // that is not.
  auto traced = [&](int x, int y) { return cost.at(x, cost.y0 + y).traced_span; };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!traced(x, y)) continue;
      const bool edge = (x > 0 && !traced(x - 1, y)) || (x + 1 < w && !traced(x + 1, y)) ||
                        (y > 0 && !traced(x, y - 1)) || (y + 1 < h && !traced(x, y + 1));
      if (edge) put(img, x, y, kTracedOutline);
    }
  }
  draw_legend(img, top);
  return img;
}

}  // namespace locus
