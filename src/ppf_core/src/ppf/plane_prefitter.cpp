#include "ppf_core/ppf/plane_prefitter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ppf_core/ppf/ipca.hpp"
#include "ppf_core/ppf/ransac.hpp"

namespace ppf {

const char* PrefitStopName(PrefitStop stop) {
  switch (stop) {
    case PrefitStop::kEmptyInput:
      return "empty_input";
    case PrefitStop::kFewRemaining:
      return "few_remaining";
    case PrefitStop::kMaxPlanes:
      return "max_planes";
    case PrefitStop::kRansacFailed:
      return "ransac_failed";
  }
  return "unknown";
}

// `config` was validated once, by the facade (ValidateConfig in config.cpp).
PlanePrefitter::PlanePrefitter(const PpfConfig& config) : config_(config) {}

bool PlanePrefitter::SplitAndCheckShape(const Plane& plane) {
  // Strict inliers only: the semi-inliers and outliers are listed once the plane is accepted.
  LabelSandwich(remaining_, plane, config_.delta, config_.semi_band_factor, &labels_, &split_);
  // Thickness first: it needs no trigonometry and rejects most slabs through vegetation.
  if (config_.max_band_rms_ratio > 0.0 && !split_.strict.empty()) {
    double sum = 0.0, sum2 = 0.0;
    for (int pos : split_.strict) {
      const double e = plane.SignedDistance(Eigen::Vector3d(remaining_[pos].cast<double>()));
      sum += e;
      sum2 += e * e;
    }
    const double n = static_cast<double>(split_.strict.size());
    const double var = std::max(0.0, sum2 / n - (sum / n) * (sum / n));
    if (std::sqrt(var) > config_.max_band_rms_ratio * config_.delta) return false;
  }
  if (!(config_.min_elevation_spread_deg > 0.0)) return true;
  // The scan is in the LiDAR frame here, so each beam has one elevation angle whatever the
  // sensor's attitude; this holds for a tilted or hand-held sensor too. Percentiles, not the
  // extremes: a few points of a neighbouring beam (or noise) inside the band must not make one
  // beam's circle look like a surface. The percentiles are taken of tan(elevation) = z / |xy|,
  // which orders the points as the elevation does, and only the two picked are turned into
  // angles: one division per point instead of an atan2 and a hypot.
  elevation_.clear();
  elevation_.reserve(split_.strict.size());
  for (int pos : split_.strict) {
    const Eigen::Vector3f& p = remaining_[pos];
    const float xy = std::sqrt(p.x() * p.x() + p.y() * p.y());
    // Straight above or below the sensor: +-inf, the elevation's +-90 degrees.
    elevation_.push_back(xy > 0.0f ? p.z() / xy
                                   : (p.z() > 0.0f   ? std::numeric_limits<float>::infinity()
                                      : p.z() < 0.0f ? -std::numeric_limits<float>::infinity()
                                                     : 0.0f));
  }
  if (elevation_.size() < 2) return false;
  const auto at = [&](double q) {
    const size_t k = static_cast<size_t>(q * static_cast<double>(elevation_.size() - 1));
    std::nth_element(elevation_.begin(), elevation_.begin() + k, elevation_.end());
    return std::atan(static_cast<double>(elevation_[k]));
  };
  const double spread_deg = (at(0.95) - at(0.05)) * 180.0 / M_PI;
  return spread_deg >= config_.min_elevation_spread_deg;
}

void PlanePrefitter::Reject(const Plane& plane, PrefitResult* result) {
  // A semi factor of 1 labels every point strict or outlier: the strict band goes to the
  // scattered points, the rest stays.
  LabelSandwich(remaining_, plane, config_.delta, 1.0, &labels_, &split_);
  for (int pos : split_.strict) result->scattered_indices.push_back(remaining_index_[pos]);
  KeepOutliers(&result->discarded_indices);
}

void PlanePrefitter::Accept(const Plane& plane, bool from_guess, int64_t track_id,
                            int ipca_iterations, PrefitResult* result) {
  const int plane_id = static_cast<int>(result->planes.size());
  FittedPlane fitted;
  fitted.plane = plane;
  fitted.from_guess = from_guess;
  fitted.guess_track_id = from_guess ? track_id : -1;
  fitted.ipca_iterations = ipca_iterations;
  fitted.num_inliers = static_cast<int>(split_.strict.size());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int pos : split_.strict) {
    sum += remaining_[pos].cast<double>();
    result->skeleton_indices.push_back(remaining_index_[pos]);
    result->skeleton_plane.push_back(plane_id);
  }
  if (!split_.strict.empty()) fitted.centroid = sum / static_cast<double>(split_.strict.size());
  for (int pos : split_.strict) {
    const Eigen::Vector3d q = remaining_[pos].cast<double>() - fitted.centroid;
    fitted.scatter.noalias() += q * q.transpose();
  }
  result->planes.push_back(fitted);

  KeepOutliers(&result->discarded_indices);
}

void PlanePrefitter::KeepOutliers(std::vector<int>* discarded) {
  // One pass over the labels: the semi-inliers are discarded, the outliers stay for the next
  // round (no lists of either in between).
  constexpr uint8_t kSemi = static_cast<uint8_t>(SandwichClass::kSemi);
  constexpr uint8_t kOutlier = static_cast<uint8_t>(SandwichClass::kOutlier);
  const size_t n = std::min(labels_.size(), remaining_.size());
  // Every point is copied and the count advances past the outliers only (no branch on the
  // common label); local pointers, which the discarded list's push_back does not make the loop
  // reload.
  next_points_.resize(n);
  next_index_.resize(n);
  const uint8_t* label = labels_.data();
  const Eigen::Vector3f* point = remaining_.data();
  const int* index = remaining_index_.data();
  Eigen::Vector3f* next_point = next_points_.data();
  int* next_index = next_index_.data();
  size_t k = 0;
  for (size_t pos = 0; pos < n; ++pos) {
    next_point[k] = point[pos];
    next_index[k] = index[pos];
    k += label[pos] == kOutlier ? 1 : 0;
    if (label[pos] == kSemi) discarded->push_back(index[pos]);
  }
  next_points_.resize(k);
  next_index_.resize(k);
  remaining_.swap(next_points_);
  remaining_index_.swap(next_index_);
}

void PlanePrefitter::TakeFinite(const std::vector<Eigen::Vector3f>& points,
                                PrefitResult* result) {
  remaining_.clear();
  remaining_index_.clear();
  remaining_.reserve(points.size());
  remaining_index_.reserve(points.size());
  float max_norm2 = 0.0f;
  for (size_t i = 0; i < points.size(); ++i) {
    if (points[i].allFinite()) {
      remaining_.push_back(points[i]);
      remaining_index_.push_back(static_cast<int>(i));
      max_norm2 = std::max(max_norm2, points[i].squaredNorm());
    } else {
      result->discarded_indices.push_back(static_cast<int>(i));
    }
  }
  // Above the largest |p| of the working set, whatever it shrinks to (the float sum's rounding
  // covered by the factor).
  max_norm_ = std::sqrt(static_cast<double>(max_norm2)) * (1.0 + 1e-5);
}

bool PlanePrefitter::ShouldStop(double min_remaining, PrefitResult* result) const {
  if (remaining_.size() < 3) {
    result->stop = result->planes.empty() ? PrefitStop::kEmptyInput : PrefitStop::kFewRemaining;
    return true;
  }
  if (static_cast<double>(remaining_.size()) < min_remaining) {
    result->stop = PrefitStop::kFewRemaining;
    return true;
  }
  if (static_cast<int>(result->planes.size()) >= config_.max_planes_per_scan) {
    result->stop = PrefitStop::kMaxPlanes;
    return true;
  }
  return false;
}

bool PlanePrefitter::FitGuesses(const std::vector<PlaneGuess>& guesses, int least,
                                double min_remaining, PrefitResult* result) {
  for (const PlaneGuess& guess : guesses) {
    if (ShouldStop(min_remaining, result)) return true;
    ++result->guesses_tried;
    // Cheap check first: most wrong guesses die here without any PCA.
    if (CountPlaneInliers(remaining_, guess.plane, config_.delta) < least) continue;
    const IpcaResult refined = RefinePlaneIpca(remaining_, guess.plane, config_.delta,
                                               config_.ipca_iterations_guess, least, max_norm_);
    if (!refined.success) continue;
    // A rejected guess leaves its points for RANSAC, like any other failed guess.
    if (!SplitAndCheckShape(refined.plane)) {
      ++result->shape_rejected;
      continue;
    }
    ++result->guesses_accepted;
    Accept(refined.plane, true, guess.track_id, refined.iterations, result);
  }
  return false;
}

void PlanePrefitter::FitNewPlanes(int least, double min_remaining, PrefitResult* result) {
  RansacParams params;
  params.delta = config_.delta;
  params.min_inliers = least;
  params.max_iterations = config_.ransac_max_iterations;
  params.confidence = config_.ransac_confidence;
  params.max_degenerate_samples = config_.ransac_max_degenerate_samples;
  params.min_sample_area = config_.ransac_min_sample_area;
  SplitMix64 rng(config_.ransac_seed);
  while (!ShouldStop(min_remaining, result)) {
    ++result->ransac_runs;
    const RansacResult fit = FitPlaneRansac(remaining_, params, &rng);
    result->ransac_iterations += fit.iterations;
    if (!fit.success) {
      result->stop = PrefitStop::kRansacFailed;
      return;
    }
    const IpcaResult refined = RefinePlaneIpca(remaining_, fit.plane, config_.delta,
                                               config_.ipca_iterations_new, least, max_norm_);
    if (refined.success) {
      if (SplitAndCheckShape(refined.plane)) {
        Accept(refined.plane, false, -1, refined.iterations, result);
        continue;
      }
      ++result->shape_rejected;
    } else {
      ++result->refine_failures;
    }
    // Ambiguous surface (oscillating or collapsing refinement) or not a surface: no skeleton
    // plane here. The RANSAC plane's band goes to the scattered set, where kNN handles it, and
    // fitting continues on the rest. That band holds at least plane_least_inliers points, so the
    // loop always makes progress.
    Reject(fit.plane, result);
  }
}

void PlanePrefitter::Fit(const std::vector<Eigen::Vector3f>& points,
                         const std::vector<PlaneGuess>& guesses, PrefitResult* result) {
  *result = PrefitResult{};
#ifdef _OPENMP
  const int saved_threads = omp_get_max_threads();
  if (config_.num_threads > 0) omp_set_num_threads(config_.num_threads);
#endif
  TakeFinite(points, result);
  const double min_remaining =
      config_.min_remaining_ratio * static_cast<double>(remaining_.size());
  const int least = std::max(3, config_.plane_least_inliers);
  const bool stopped = config_.incremental_fitting
                           ? FitGuesses(guesses, least, min_remaining, result)
                           : ShouldStop(min_remaining, result);
  if (!stopped) FitNewPlanes(least, min_remaining, result);

  result->scattered_indices.insert(result->scattered_indices.end(), remaining_index_.begin(),
                                   remaining_index_.end());
  std::sort(result->scattered_indices.begin(), result->scattered_indices.end());
  std::sort(result->discarded_indices.begin(), result->discarded_indices.end());
#ifdef _OPENMP
  if (config_.num_threads > 0) omp_set_num_threads(saved_threads);
#endif
}

}  // namespace ppf
