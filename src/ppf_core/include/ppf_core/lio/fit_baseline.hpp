// What the recent LIO scans' posteriors scored on the map, for the consistency check
// (lio_ppf_process.cpp, OverruleIfInconsistent): a scan is searched again when its fit falls far
// below the recent scans' median, or the scan alone would move it well beyond their steps.
//
// Why per kind: a scan is scored from the kNN rows' own associations when enough of its points
// met the map, otherwise on a sample of the whole scan searched afresh. The two are different
// statistics of the same pose: in kPpf, whose kNN map holds only the scattered points, a sample
// of the whole scan fits 0.4-0.7 where the associations of the same undisturbed scans give
// 0.95-1.0. Judged against one shared median, every scan with too few associations looked like
// a map contradicting its pose (docs/decisions.md, "Consistency check"). Each score is compared
// only with the recent scores of its own kind, and a kind needs min_scans of its own before it
// judges anything, as the check does after a start.
#pragma once

#include <algorithm>
#include <cstddef>
#include <deque>
#include <vector>

namespace ppf {

// The upper median (element size/2 in order, the upper of the two middles for an even count);
// 0 for none. Shared by the consistency check and the LiDAR-only fit gate so that both judge a
// fit by the same statistic.
inline double UpperMedian(const std::deque<double>& values) {
  if (values.empty()) return 0.0;
  std::vector<double> v(values.begin(), values.end());
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(mid), v.end());
  return v[mid];
}

class FitBaseline {
 public:
  enum class Kind { kAssociated = 0, kSampled = 1 };

  struct Options {
    size_t window = 10;    // scans remembered per kind
    size_t min_scans = 5;  // a kind judges once it holds this many
  };

  FitBaseline() = default;
  explicit FitBaseline(const Options& options) : options_(options) {}

  void Remember(Kind kind, double fit, double step_pos_m) {
    History& h = history(kind);
    h.fits.push_back(fit);
    h.steps_pos.push_back(step_pos_m);
    while (h.fits.size() > options_.window) h.fits.pop_front();
    while (h.steps_pos.size() > options_.window) h.steps_pos.pop_front();
  }

  bool Ready(Kind kind) const { return history(kind).fits.size() >= options_.min_scans; }
  size_t Size(Kind kind) const { return history(kind).fits.size(); }

  // Medians (upper, for an even count) of the remembered scans of that kind; 0 when none.
  double MedianFit(Kind kind) const { return UpperMedian(history(kind).fits); }
  double MedianStepPos(Kind kind) const { return UpperMedian(history(kind).steps_pos); }

  void Clear() {
    for (History& h : kinds_) {
      h.fits.clear();
      h.steps_pos.clear();
    }
  }

 private:
  struct History {
    std::deque<double> fits;
    std::deque<double> steps_pos;
  };

  History& history(Kind kind) { return kinds_[static_cast<int>(kind)]; }
  const History& history(Kind kind) const { return kinds_[static_cast<int>(kind)]; }

  Options options_;
  History kinds_[2];
};

}  // namespace ppf
