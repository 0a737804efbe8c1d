#include "common/scan/pixel_samples.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace locus {
namespace {

// Adaptive refinement inside ray-traced spans (issue #6 item 3;
// PixelSamples::traced_colour): a traced piece is interpolated from its
// pixel's corner samples where they (and, for N >= 8, the pixel's interior
// grid) see one material and differ by at most kContrast / max(1, N / 4)
// (largest channel, linear radiance), blended out as the spread grows to
// twice that. The threshold falls with N so that the error keeps falling as
// N grows: with 0.05 at every N, the interpolated refracted and reflected
// images left a floor (SPD mount at 256x256: --aa 8 0.0024, --aa 16 0.0020
// RMSE; with the threshold falling, 0.0017 and 0.00076 for 21-24% more
// time; docs/multiscan.md). N = 4 is unchanged.
// Otherwise it takes the mean radiance of the samples of a stratified grid
// inside the pixel (2 max(1, N / 4) squared) that see its material.
constexpr double kContrast = 0.05;

// A silhouette's pixel (its corners see different materials; N < 8)
// estimates each material's radiance from the samples that see it: three
// inside (weight 1 each) and the four corners (this weight each). Measured
// against --spp 16 on rings, balls, (b) and (d) at 256²: 1/2 gives lower
// RMSE than 1/8, 1/4, 3/4 or 1 (docs/multiscan.md).
constexpr double kSilhouetteCorner = 0.5;

// At N = 1 (PixelSamples::centre_only_) the sub-scanlines lie one per pixel
// row, and the paper would trace one ray per pixel of a traced span (§3.3).
// A pixel its corners do not settle (a silhouette, or an edge of the
// reflected or refracted image: step 3 of traced_colour) then traces its
// centre alone and weighs it with the corners that see the material, as a
// silhouette does at N < 8 without its two diagonal fine points: one ray
// where the 2 x 2 fine grid took four. Measured side by side at 256x256,
// one thread, against raytrace --spp 16 (docs/multiscan.md, "Session 35"):
// render 0.58-0.84x, RMSE +3-14%, error x sqrt(time) lower on (b), (d),
// balls, gears and rings and equal on (a); at N = 2 the same rule lost on
// balls and gears (RMSE +35% and +21% for 0.63x and 0.75x), so it stops at
// N = 1.

}  // namespace

// The lookups of samples (corner, fine_point, grid_samples, grid_point) are
// used in this file only and are defined `inline`, so that the compiler
// inlines them into traced_colour as it did when they were written in the
// class.

PixelSamples::PixelSamples(const PreparedScene& ps, Tracer& tracer, EyeCandidates& eye,
                           Stats& stats, int aa, int j0, int j1)
    : ps_(ps),
      cam_(ps.camera),
      tracer_(tracer),
      eye_(eye),
      stats_(stats),
      j0_(j0),
      j1_(j1),
      grid_(std::max(1, aa / 4)),
      centre_only_(aa <= 1),
      lattice_(static_cast<size_t>(ps.camera.width) + 1),
      interior_(static_cast<size_t>(ps.camera.width) * grid_ * grid_),
      fine_(static_cast<size_t>(ps.camera.width) * 4 * grid_ * grid_) {}

void PixelSamples::set_line(double y) {
  y_ = y;
  // Both rows stay inside [j0, j1 - 1), so that traced_colour's lattice
  // rows j and j + 1 are inside [j0, j1].
  const int below = static_cast<int>(std::floor(y));
  row_down_ = below >= j0_ && below < j1_ - 1 && below < cam_.height ? below : -1;
  row_up_ = y == below && below - 1 >= j0_ && below - 1 < j1_ - 1 ? below - 1 : -1;
}

// The paper samples every piece: one ray per pixel per sub-scanline (§3.3).
// Where the surface is smooth, that sample is, within kContrast, the
// bilinear interpolation of the samples at the pixel's corners, which all
// sub-scanlines of the pixel and of its neighbours share. So if the corners
// that have a weight here (each traced once, lazily) all see the piece's
// material and differ by at most kContrast, the piece is interpolated; for
// N >= 8 the pixel's interior grid must agree too, so that a feature inside
// the pixel that no corner sees is found as N grows. Otherwise (an edge in
// the reflected or refracted image, or a silhouette in the pixel: issue #6
// item 3's adaptive refinement) the piece's radiance is the mean of the
// samples of the pixel's fine grid (stratified, traced once for all its
// sub-scanlines) that see its material: with the exact coverage of each
// piece, the pixel is then the box filter's integral of each material's
// radiance, estimated from the samples inside it. Where the corners see
// different materials at N < 8 (a silhouette crosses the pixel), fewer fine
// samples do: the pixel's centre and the two fine points on its main
// diagonal, with its corners (kSilhouetteCorner); at N = 1 every pixel
// the corners do not settle takes its centre and corners alone
// (centre_only_). A piece whose material none of those samples sees (a
// sliver thinner than their spacing) is sampled itself (`direct(x)`;
// docs/multiscan.md).
template <class Direct>
Color PixelSamples::traced_colour(double x0, double x1, int hit, int j, Direct&& direct) {
  const int material = material_of(hit);
  const double xm = 0.5 * (x0 + x1);
  const int i = clamped_floor(xm, 0, cam_.width - 1);
  const double fx = xm - i, fy = y_ - j;
  const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  Color lo(kInf), hi(-kInf), acc(0.0);
  bool smooth = true;
  auto agree = [&](const Corner& k) {
    if (k.material != material) return false;
    lo = glm::min(lo, k.colour);
    hi = glm::max(hi, k.colour);
    return true;
  };
  for (int c = 0; c < 4 && smooth; ++c) {
    if (!(w[c] > 0)) continue;
    const Corner& k = corner(i + (c & 1), j + (c >> 1));
    smooth = agree(k);
    acc += w[c] * k.colour;
  }
  if (smooth && grid_ >= 2) {
    const Corner* in = interior(i, j);
    for (int q = 0; q < grid_ * grid_ && smooth; ++q) smooth = agree(in[q]);
  }
  // The interpolation's weight falls from 1 to 0 as the spread goes from
  // the threshold to twice that (no jump where it crosses).
  const double contrast = kContrast / grid_;
  const double keep = smooth ? std::clamp(2.0 - max_component(hi - lo) / contrast, 0.0, 1.0) : 0.0;
  if (keep >= 1.0) return acc;
  // The mean of the samples of the pixel that see the material.
  Color mean;
  if (grid_ == 1 && (!smooth || centre_only_)) {
    // A silhouette (and at N = 1 any pixel its corners do not settle).
    Color sum(0.0);
    double weight = 0;
    auto add = [&](const Corner& k, double w) {
      if (k.material != material) return;
      sum += w * k.colour;
      weight += w;
    };
    add(*interior(i, j), 1.0);
    if (!centre_only_) {
      add(fine_point(i, j, 0), 1.0);
      add(fine_point(i, j, 3), 1.0);
    }
    for (int c = 0; c < 4; ++c) add(corner(i + (c & 1), j + (c >> 1)), kSilhouetteCorner);
    mean = weight > 0 ? sum / weight : direct(xm);
  } else {
    // The fine grid.
    const int g = 2 * grid_;
    const Corner* in = fine(i, j);
    Color sum(0.0);
    int n = 0;
    for (int q = 0; q < g * g; ++q) {
      if (in[q].material == material) {
        sum += in[q].colour;
        ++n;
      }
    }
    mean = n > 0 ? sum / static_cast<double>(n) : direct(xm);
  }
  return keep > 0 ? keep * acc + (1.0 - keep) * mean : mean;
}

PieceColours PixelSamples::colours(double x0, double x1, int hit,
                                   FunctionRef<Color(double)> direct) {
  // A sliver's own sample is the same ray for both rows: traced once.
  std::optional<Color> own;
  auto once = [&](double x) {
    if (!own) own = direct(x);
    return *own;
  };
  PieceColours c;
  if (row_down_ >= 0) c.colour = traced_colour(x0, x1, hit, row_down_, once);
  if (row_up_ >= 0) c.colour_up = traced_colour(x0, x1, hit, row_up_, once);
  return c;
}

inline const PixelSamples::Corner* PixelSamples::grid_samples(int i, int j, int g, RowRing& store) {
  const int n = g * g;
  Corner* in = store.row(j) + static_cast<size_t>(i) * n;
  for (int q = 0; q < n; ++q) grid_point(in[q], i, j, g, q);
  return in;
}

inline const PixelSamples::Corner& PixelSamples::fine_point(int i, int j, int q) {
  const int g = 2 * grid_;
  Corner& k = fine_.row(j)[static_cast<size_t>(i) * g * g + q];
  grid_point(k, i, j, g, q);
  return k;
}

inline void PixelSamples::grid_point(Corner& k, int i, int j, int g, int q) {
  if (k.done) return;
  k.done = true;
  ++stats_.rays_eye;
  const double x = i + (q % g + 0.5) / g, y = j + (q / g + 0.5) / g;
  const Ray ray{cam_.from, cam_.direction(x, y)};
  const auto hit = eye_.nearest_in_square(tracer_, ray, cam_.hither, x, y);
  k.material = hit ? material_of(hit->prim) : -1;
  k.colour = hit ? tracer_.shade(ray, *hit, 1, 1.0, nullptr) : ps_.scene.background;
}

inline const PixelSamples::Corner& PixelSamples::corner(int i, int j) {
  Corner& k = lattice_.row(j)[i];
  if (!k.done) {
    k.done = true;
    ++stats_.rays_eye;
    const Ray ray{cam_.from, cam_.direction(i, j)};
    const auto hit = eye_.nearest_in_square(tracer_, ray, cam_.hither, i, j);
    if (hit) {
      k.material = material_of(hit->prim);
      k.colour = tracer_.shade(ray, *hit, 1, 1.0, nullptr);
    } else {
      k.colour = ps_.scene.background;
    }
  }
  return k;
}

}  // namespace locus
