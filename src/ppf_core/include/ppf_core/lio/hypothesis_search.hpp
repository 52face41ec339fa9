// Registration from several initial guesses: the LiDAR-only mode's answer to a poor prediction.
//
// Without an IMU the prediction is the constant-velocity model (motion_model.hpp). A hand-held
// sensor at sparse keyframes turns several degrees between scans, and its turn rate changes by
// tens of degrees from one interval to the next (docs/decisions.md, "Several guesses without an
// IMU"), so the guess can be tens of degrees off; the kNN registration only reaches about one
// voxel neighbourhood (1 m at the 0.5 m map), i.e. a few degrees at the ranges that dominate a
// scan. So each guess is first aligned coarsely (a sample of the scan, a wide residual gate, more
// iterations, no refined gate), its converged fit scored (the share of sample points with a map
// plane within fit_gate), and the best becomes the prediction of the normal update (and of the
// skeleton tracker's incremental plane guesses). The constant-velocity guess comes first and is kept at once when it fits
// well: the others cost time only where the model failed.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/lio/iekf.hpp"
#include "ppf_core/lio/knn_residual.hpp"
#include "ppf_core/lio/residual_provider.hpp"

namespace ppf {

struct MotionHypothesis {
  std::string name;
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
};

struct CoarseAlignment {
  // The best guess after its coarse alignment, the guess's name, its fit (ScoreFit) and how
  // many guesses were aligned.
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
  std::string name;
  double fit = 0.0;
  int tried = 0;
};

// Aligns the hypotheses in order until one reaches good_fit; returns the one with the most
// inliers (ScoreFit) among those aligned. `frame` holds the scan and the map (its labels are
// ignored: every point takes part). Empty hypotheses or an empty frame: fit 0, the first
// hypothesis (or identity) unchanged.
CoarseAlignment AlignHypotheses(const ScanFrame& frame,
                                const std::vector<MotionHypothesis>& hypotheses,
                                const LidarOnlyOptions& options, const IekfOptions& iekf,
                                const KnnOptions& knn);

// How well a pose puts the frame's points (all labels) on the map. covered: points with k map
// neighbours within knn.max_neighbor_distance; inliers: of those, points within fit_gate of the
// plane their neighbours span. fit = inliers / covered (0 if under 5 % of the points are
// covered). Over covered points, not all: in kPpf the kNN map holds only the scattered points,
// so a scan's planar surfaces find nothing there even at the right pose, and a share of all
// points would sink as the map ages at a right pose (docs/decisions.md, "Relative good fit").
struct FitScore {
  size_t inliers = 0;
  size_t covered = 0;
  double fit = 0.0;
};
// Every n-th point of the frame, at most max_points of them (all if max_points <= 0), all
// labelled kScattered; map and extrinsic as the frame's. `kept` (if non-null) receives the frame
// index of each sampled point, for what the frame carries beside its points (their times).
ScanFrame SampleFrame(const ScanFrame& frame, int max_points, std::vector<size_t>* kept = nullptr);

FitScore ScoreFit(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                  const LidarOnlyOptions& options, const KnnOptions& knn);

// ScoreFit plus what the scan alone says about the pose, from the same neighbours: one
// Gauss-Newton step of the point-to-plane rows within `wide_gate` (no prior, equal weights),
// rotation about the LiDAR's position and translation, both in the world frame. Directions the
// rows do not constrain (eigenvalues of their J^T J below the IEKF's degeneracy thresholds) take
// no step. A pose the IMU got wrong by what the narrow gates hide shows here as a long step.
struct PoseProbe {
  FitScore score;
  Eigen::Vector3d step_rot = Eigen::Vector3d::Zero();  // rad, world frame
  Eigen::Vector3d step_pos = Eigen::Vector3d::Zero();  // m, world frame
  Eigen::Vector3d step_vel = Eigen::Vector3d::Zero();  // m/s, world frame (ProbePoseAndVelocity)
  // The position step in standard deviations of its own estimate (the rows' scatter about it);
  // 0 with too few rows to tell.
  double step_pos_sigmas = 0.0;
  size_t rows = 0;
};
PoseProbe ProbePose(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                    const LidarOnlyOptions& options, const KnnOptions& knn,
                    const IekfOptions& iekf, double wide_gate);

// ProbePose from associations already made (KnnResidualProvider::Associations: the IEKF's last
// kNN search of the scan), without searching the map again: each point with whether it met the
// map (k neighbours) and the plane they fitted. The score counts these points, not a sample.
// Only the first step_points of them give the step's rows (all by default); the score counts
// every one.
PoseProbe ProbePoseAssociated(const std::vector<AssociatedPoint>& points,
                              const Eigen::Isometry3d& T_world_lidar,
                              const LidarOnlyOptions& options, const IekfOptions& iekf,
                              double wide_gate, size_t step_points = SIZE_MAX);

// ProbePose with the velocity the scan was taken at: dt holds each frame point's time from the
// scan end (seconds, <= 0), and a world velocity v moves the point by v * dt. The de-skew's
// smear is what observes it: a scan de-skewed with the wrong speed bends the walls it saw early
// against those it saw late. Directions of the velocity the rows do not pin take no step, nor
// does the velocity along fixed_axis (zero vector: none fixed).
PoseProbe ProbePoseAndVelocity(const ScanFrame& frame, const std::vector<float>& dt,
                               const Eigen::Vector3d& fixed_axis,
                               const Eigen::Isometry3d& T_world_lidar,
                               const LidarOnlyOptions& options, const KnnOptions& knn,
                               const IekfOptions& iekf, double wide_gate);

}  // namespace ppf
