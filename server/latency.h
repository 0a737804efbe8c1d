// A latency histogram of fixed size: 8 buckets per octave from 1 us, so a
// percentile is known within 9% however many samples were taken. Memory
// stays bounded over a coordinator's life.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>

namespace locus::farm {

struct LatencySummary {
  uint64_t count = 0;
  double p50_us = 0;
  double p99_us = 0;
  double max_us = 0;
};

class LatencyHistogram {
 public:
  void add(std::chrono::nanoseconds d) {
    const double us = std::max(1.0, d.count() / 1000.0);
    const int i = std::min(kBuckets - 1, static_cast<int>(std::log2(us) * kPerOctave));
    ++buckets_[i];
    ++count_;
    max_us_ = std::max(max_us_, us);
  }

  LatencySummary summary() const {
    LatencySummary s;
    s.count = count_;
    s.max_us = max_us_;
    s.p50_us = percentile(0.50);
    s.p99_us = percentile(0.99);
    return s;
  }

 private:
  static constexpr int kPerOctave = 8;
  static constexpr int kBuckets = 28 * kPerOctave;  // up to ~2.7 minutes

  // The upper edge of the bucket holding the q-th sample (capped by the max).
  double percentile(double q) const {
    if (count_ == 0) return 0;
    const uint64_t rank = static_cast<uint64_t>(std::ceil(q * count_));
    uint64_t seen = 0;
    for (int i = 0; i < kBuckets; ++i) {
      seen += buckets_[i];
      if (seen >= rank) return std::min(max_us_, std::exp2((i + 1.0) / kPerOctave));
    }
    return max_us_;
  }

  std::array<uint64_t, kBuckets> buckets_{};
  uint64_t count_ = 0;
  double max_us_ = 0;
};

}  // namespace locus::farm
