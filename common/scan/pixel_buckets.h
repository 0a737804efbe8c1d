// Items (intervals, faces) bucketed by the pixel columns they meet, so that
// a point looks only at those over its pixel (compressed rows: one array of
// item indices, pixel i's at [first[i], first[i + 1]), each in item order).
#pragma once

#include <vector>

namespace locus {

class PixelBuckets {
 public:
  // `pixels(k, fn)` calls fn(i) once for each pixel column i in [0, width)
  // that item k of `items` meets.
  template <class Pixels>
  void build(int width, int items, Pixels&& pixels) {
    first_.assign(width + 1, 0);
    for (int k = 0; k < items; ++k) pixels(k, [&](int i) { ++first_[i + 1]; });
    for (int i = 0; i < width; ++i) first_[i + 1] += first_[i];
    at_.resize(first_[width]);
    fill_.assign(first_.begin(), first_.end() - 1);
    for (int k = 0; k < items; ++k) pixels(k, [&](int i) { at_[fill_[i]++] = k; });
  }
  void clear() { first_.clear(); }
  bool empty() const { return first_.empty(); }
  // Calls fn(k) for the items over pixel i, in item order, until it
  // returns true; returns whether one did.
  template <class Fn>
  bool visit(int i, Fn&& fn) const {
    for (int k = first_[i]; k < first_[i + 1]; ++k) {
      if (fn(at_[k])) return true;
    }
    return false;
  }

 private:
  std::vector<int> first_, at_, fill_;
};

}  // namespace locus
