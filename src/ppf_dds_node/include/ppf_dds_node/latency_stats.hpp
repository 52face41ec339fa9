// Percentiles of a latency series. Keeps every sample of the run (8 bytes per scan: ~3 MB for a
// 10 h run at 10 Hz), so the final summary is exact rather than a sketch.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
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

}  // namespace ppf::dds
