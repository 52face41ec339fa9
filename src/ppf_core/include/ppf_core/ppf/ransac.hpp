// Single-plane RANSAC, the "fit" step of fit-remove-fit (paper Sec. IV-A1).
//
// Deterministic for a given seed and input regardless of the OpenMP thread count: hypotheses are
// drawn serially from a private generator in fixed-size batches, scored in parallel, and the best
// is chosen in batch order (ties keep the earlier hypothesis).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/ppf/plane.hpp"

namespace ppf {

// Small, portable PRNG (splitmix64): std:: distributions differ between standard libraries, and
// reproducible plane ids/results across builds matter more than statistical finesse here.
class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  // Uniform in [0, n) for n > 0 (multiply-high; bias is negligible for point-cloud sizes).
  uint32_t Below(uint32_t n) {
    return static_cast<uint32_t>(((Next() >> 32) * static_cast<uint64_t>(n)) >> 32);
  }

 private:
  uint64_t state_;
};

struct RansacParams {
  double delta = 0.1;                // inlier band |n.p + d| < delta
  int min_inliers = 150;             // below this the fit fails
  int max_iterations = 300;          // cap on the adaptive iteration count
  double confidence = 0.99;          // p in k = log(1-p)/log(1-w^3)
  int max_degenerate_samples = 300;  // give up after this many rejected samples
  double min_sample_area = 1e-4;     // |(p1-p0)x(p2-p0)| below this -> degenerate sample
};

struct RansacResult {
  bool success = false;
  Plane plane;
  int num_inliers = 0;         // of the best hypothesis counted in full
  int iterations = 0;          // scored hypotheses
  int degenerate_samples = 0;  // rejected samples (coincident or collinear)
  // Hypotheses rejected on a point subset (ransac.cpp): scored, but not counted in full.
  int pretest_rejected = 0;
  // Hypotheses whose full count stopped once they could no longer beat the best one (ransac.cpp):
  // scored, but with no exact count. Never changes the result.
  int count_abandoned = 0;
};

// Adaptive RANSAC iteration count for inlier ratio w and confidence p, capped at max_iterations.
int RansacIterationsNeeded(double inlier_ratio, double confidence, int max_iterations);

// Fits one plane to `points`. Fails (success=false) for fewer than 3 points, when no
// non-degenerate sample can be drawn, or when the best plane has < min_inliers inliers.
// `rng` is advanced, so successive calls on one scan draw different samples.
RansacResult FitPlaneRansac(const std::vector<Eigen::Vector3f>& points, const RansacParams& params,
                            SplitMix64* rng);

// Number of points with |n.p + d| < delta (OpenMP-parallel).
int CountPlaneInliers(const std::vector<Eigen::Vector3f>& points, const Plane& plane, double delta);

}  // namespace ppf
