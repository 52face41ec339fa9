// Plane pre-fitting (PPF) of one de-skewed, downsampled scan: fit-remove-fit (paper Sec. IV-A).
//
// 1. Incremental guesses (if enabled): window planes moved into this scan's frame with the
//    IMU-predicted pose (Theorem 1). A guess is accepted only if >= plane_least_inliers points lie
//    within delta of it and its iPCA (ipca_iterations_guess) neither oscillates nor loses support.
// 2. Fresh RANSAC on what remains, one plane at a time, each refined by iPCA
//    (ipca_iterations_new).
// After each accepted plane the sandwich layer removes its strict inliers (skeleton points) and
// discards its semi-inliers. Fitting stops when fewer than min_remaining_ratio of the input remain,
// max_planes_per_scan planes are accepted, or RANSAC fails. Whatever is left is scattered (Theta).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/ppf/plane.hpp"
#include "ppf_core/ppf_config.hpp"
#include "ppf_core/ppf/sandwich_layer.hpp"

namespace ppf {

// A window plane expressed in the current scan's frame, tried before RANSAC.
struct PlaneGuess {
  Plane plane;            // in the scan (LiDAR) frame
  int64_t track_id = -1;  // window track it came from (carried into FittedPlane)
};

struct FittedPlane {
  Plane plane;                                         // refined, scan (LiDAR) frame
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // of its strict inliers, scan frame
  // Sum of (p - centroid)(p - centroid)^T over the strict inliers, scan frame: with centroid and
  // num_inliers the plane's full second moments (extent, thickness, multi-scan fits).
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  int num_inliers = 0;                                 // its skeleton points
  bool from_guess = false;
  int64_t guess_track_id = -1;  // the track whose guess produced it; -1 for RANSAC planes
  int ipca_iterations = 0;
};

enum class PrefitStop : uint8_t {
  kEmptyInput,    // fewer than 3 valid points
  kFewRemaining,  // remaining < min_remaining_ratio * input
  kMaxPlanes,     // max_planes_per_scan accepted
  kRansacFailed,  // best RANSAC plane had < plane_least_inliers inliers (or only degenerate
                  // samples)
};

const char* PrefitStopName(PrefitStop stop);

struct PrefitResult {
  std::vector<FittedPlane> planes;
  // Omega: indices into the input of strict inliers, grouped by plane; skeleton_plane[i] is the
  // index into `planes` of skeleton_indices[i].
  std::vector<int> skeleton_indices;
  std::vector<int> skeleton_plane;
  std::vector<int> scattered_indices;  // Theta: keep kNN residuals; the only points for the map
  std::vector<int> discarded_indices;  // semi-inliers and non-finite points: neither
  PrefitStop stop = PrefitStop::kEmptyInput;
  int guesses_tried = 0;
  int guesses_accepted = 0;
  int ransac_runs = 0;
  int ransac_iterations = 0;  // scored hypotheses over all runs
  int refine_failures = 0;    // RANSAC planes whose iPCA failed; their band went to Theta
  // Candidates (RANSAC or guess) that failed a shape test (max_band_rms_ratio: a slab through
  // scattered points; min_elevation_spread_deg: one beam's circle); a rejected RANSAC plane's band
  // went to Theta.
  int shape_rejected = 0;
};

class PlanePrefitter {
 public:
  explicit PlanePrefitter(const PpfConfig& config);

  const PpfConfig& config() const { return config_; }

  // Pre-fits `points` (scan frame). `guesses` are used only if config.incremental_fitting.
  // A pure function of its inputs and the config (the RANSAC generator is re-seeded per call).
  void Fit(const std::vector<Eigen::Vector3f>& points, const std::vector<PlaneGuess>& guesses,
           PrefitResult* result);

 private:
  // The finite points become the working set; the others are discarded (result).
  void TakeFinite(const std::vector<Eigen::Vector3f>& points, PrefitResult* result);
  // Whether fitting must stop before the next plane (and result->stop says why).
  bool ShouldStop(double min_remaining, PrefitResult* result) const;
  // Incremental fitting: each guess refined on the working set and kept if it passes. Returns
  // whether fitting stopped.
  bool FitGuesses(const std::vector<PlaneGuess>& guesses, int least, double min_remaining,
                  PrefitResult* result);
  // New planes by RANSAC until a stop condition.
  void FitNewPlanes(int least, double min_remaining, PrefitResult* result);
  // Classifies the working set by the sandwich of `plane` (labels_; its strict inliers into
  // split_.strict) and returns whether those pass the shape tests (max_band_rms_ratio,
  // min_elevation_spread_deg; ppf_config.hpp).
  bool SplitAndCheckShape(const Plane& plane);
  // Removes the sandwich of `plane` (split_ and labels_, from SplitAndCheckShape) from the
  // working set; records the plane.
  void Accept(const Plane& plane, bool from_guess, int64_t track_id, int ipca_iterations,
              PrefitResult* result);
  // Moves the strict band of `plane` to the scattered points and keeps the rest for later rounds.
  void Reject(const Plane& plane, PrefitResult* result);
  // Makes the outliers of the last labelling (labels_) the working set; its semi-inliers go to
  // `discarded`.
  void KeepOutliers(std::vector<int>* discarded);

  PpfConfig config_;
  // Working set: remaining points (compact copy, cache-friendly) and their input indices.
  std::vector<Eigen::Vector3f> remaining_;
  std::vector<int> remaining_index_;
  double max_norm_ = 0.0;  // bounds |p| over the working set (TakeFinite), for RefinePlaneIpca
  std::vector<Eigen::Vector3f> next_points_;
  std::vector<int> next_index_;
  SandwichSplit split_;
  std::vector<uint8_t> labels_;  // SandwichClass of each working point (SplitAndCheckShape, Reject)
  std::vector<float> elevation_;  // scratch of SplitAndCheckShape: tan(elevation) per point
};

}  // namespace ppf
