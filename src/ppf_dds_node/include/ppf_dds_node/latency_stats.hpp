// Percentiles of a latency series. Keeps every sample of the run (8 bytes per scan: ~3 MB for a
// 10 h run at 10 Hz), so the final summary is exact rather than a sketch.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ppf::dds {

class LatencyStats {
 public:
  void Add(double ms) {
    if (std::isfinite(ms)) samples_.push_back(ms);
  }
  size_t count() const { return samples_.size(); }
  // Nearest-rank percentile, q in [0, 100]; NaN when empty.
  double Percentile(double q) const {
    if (samples_.empty()) return std::nan("");
    std::vector<double> s = samples_;
    const size_t rank = static_cast<size_t>(std::ceil(q / 100.0 * static_cast<double>(s.size())));
    const size_t idx = rank == 0 ? 0 : std::min(rank - 1, s.size() - 1);
    std::nth_element(s.begin(), s.begin() + static_cast<std::ptrdiff_t>(idx), s.end());
    return s[idx];
  }
  double Max() const {
    return samples_.empty() ? std::nan("") : *std::max_element(samples_.begin(), samples_.end());
  }
  // Percentile over the samples added since `from` (for periodic log lines).
  double PercentileSince(size_t from, double q) const {
    LatencyStats tail;
    for (size_t i = from; i < samples_.size(); ++i) tail.Add(samples_[i]);
    return tail.Percentile(q);
  }

 private:
  std::vector<double> samples_;
};

// Percentiles of a series too long to keep whole (one sample per IMU message: 200 Hz for hours):
// counts per bin of `bin_ms` up to `max_ms`, later samples in the last bin. A percentile is the
// upper edge of its bin (exact to one bin), the maximum is exact.
class LatencyHistogram {
 public:
  explicit LatencyHistogram(double bin_ms = 0.01, double max_ms = 100.0)
      : bin_ms_(bin_ms), bins_(static_cast<size_t>(std::ceil(max_ms / bin_ms)) + 1, 0) {}
  void Add(double ms) {
    if (!std::isfinite(ms)) return;
    const double b = std::max(0.0, ms) / bin_ms_;
    ++bins_[std::min(static_cast<size_t>(b), bins_.size() - 1)];
    ++count_;
    max_ = std::max(max_, ms);
  }
  uint64_t count() const { return count_; }
  // Nearest rank, q in [0, 100]; NaN when empty.
  double Percentile(double q) const {
    if (count_ == 0) return std::nan("");
    const uint64_t rank = std::max<uint64_t>(
        1, static_cast<uint64_t>(std::ceil(q / 100.0 * static_cast<double>(count_))));
    uint64_t seen = 0;
    for (size_t i = 0; i < bins_.size(); ++i) {
      seen += bins_[i];
      if (seen < rank) continue;
      // The last bin holds everything beyond the range: only the maximum bounds it.
      return i + 1 == bins_.size() ? max_ : std::min(max_, static_cast<double>(i + 1) * bin_ms_);
    }
    return max_;
  }
  double Max() const { return count_ == 0 ? std::nan("") : max_; }

 private:
  double bin_ms_;
  std::vector<uint64_t> bins_;
  uint64_t count_ = 0;
  double max_ = 0.0;
};

}  // namespace ppf::dds
