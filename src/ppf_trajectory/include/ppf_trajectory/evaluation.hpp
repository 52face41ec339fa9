// Trajectory evaluation the way evo computes it (evo_ape / evo_rpe, translation part):
//   1. associate: for each reference stamp the nearest estimate stamp (after adding `offset` to
//      the estimate stamps), kept if |dt| <= max_diff (default 0.01 s);
//   2. align (optional): Umeyama least squares of the estimate positions onto the reference,
//      SE(3) or Sim(3) (with scale), or position + yaw (4 DoF, the usual alignment for
//      visual- and LiDAR-inertial odometry, whose roll and pitch are observable through
//      gravity: a tilted world must show as error), or none;
//   3. APE: e_i = |p_ref_i - p_est_aligned_i|;  RPE over pairs (i, j):
//      E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), e = |trans(E)|; pairs every `delta` frames
//      (i = 0, delta, 2 delta, ...), or by travelled distance `delta` metres along the estimate;
//   4. stats: rmse, mean, median, std (population), min, max, sse.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_trajectory/trajectory_io.hpp"

namespace ppf {

enum class Alignment { kNone, kSE3, kSim3, kPosYaw };

struct ErrorStats {
  size_t count = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0, sse = 0;
};
ErrorStats ComputeStats(const std::vector<double>& errors);

// Indices (ref, est) of associated poses; ref order, evo's nearest-stamp rule.
std::vector<std::pair<size_t, size_t>> AssociateByStamp(const Trajectory& ref,
                                                        const Trajectory& est, double max_diff,
                                                        double offset);

// Umeyama: the similarity (s, R, t) minimising sum |dst_i - (s R src_i + t)|^2. with_scale=false
// forces s = 1. Returns false for fewer than 3 points or a degenerate configuration.
bool Umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
             bool with_scale, Eigen::Matrix3d* R, Eigen::Vector3d* t, double* scale);

// Least squares over rotations about the world z axis and translations: the (R = Rz(yaw), t)
// minimising sum |dst_i - (R src_i + t)|^2. Returns false for fewer than 2 points or when the
// points have no horizontal extent (yaw undefined).
bool AlignPositionYaw(const std::vector<Eigen::Vector3d>& src,
                      const std::vector<Eigen::Vector3d>& dst, Eigen::Matrix3d* R,
                      Eigen::Vector3d* t);

// Tilt of a pose relative to its reference: the angle (degrees) between the gravity direction
// seen from the body in the estimate, R_est^T e_z, and in the reference, R_ref^T e_z. Both worlds
// must be gravity-aligned with z up (ground truth is; the estimator's world is by construction).
// It needs no alignment and no alignment about world z can change it.
double TiltDeg(const Eigen::Isometry3d& T_ref, const Eigen::Isometry3d& T_est);

// What a planner trusting the odometry's "up" sees, independent of any alignment.
struct GravityMetrics {
  bool ok = false;
  std::vector<double> tilt_deg;  // TiltDeg per associated pose, reference order
  ErrorStats tilt;               // over the poses from tilt_after_s on (count 0: none)
  // Height error: the estimate's first associated pose is moved onto the reference's by
  // translation and yaw only (roll and pitch stay as estimated), then z_est - z_ref.
  double final_dz_m = 0.0;    // at the last associated pose
  double max_abs_dz_m = 0.0;  // over all associated poses
  double path_length_m = 0.0;  // reference, through the associated poses
  double FinalDzPercent() const {
    return path_length_m > 0 ? 100.0 * final_dz_m / path_length_m : 0.0;
  }
};

struct EvalOptions {
  double max_diff = 0.01;
  double offset = 0.0;
  Alignment align = Alignment::kSE3;
  // Gravity metrics: the tilt statistics cover poses whose reference stamp is at least this long
  // after the first associated one (the start can carry the initialization's own error).
  double tilt_after_s = 0.0;
  // RPE only:
  double delta = 1.0;
  bool delta_in_meters = false;  // false: delta frames (integer >= 1)
  bool pairs_from_reference = false;  // metres: measure the path on the reference (evo default: est)
};

struct EvalResult {
  bool ok = false;
  std::string error;
  size_t matched = 0;
  double scale = 1.0;  // Sim(3) scale applied to the estimate
  Eigen::Isometry3d T_ref_est = Eigen::Isometry3d::Identity();  // alignment (without scale)
  std::vector<double> errors;
  ErrorStats stats;
  GravityMetrics gravity;  // APE only (alignment-free, same associated poses)
};

EvalResult ComputeApe(const Trajectory& ref, const Trajectory& est, const EvalOptions& options);
EvalResult ComputeRpe(const Trajectory& ref, const Trajectory& est, const EvalOptions& options);

// Tilt and height error over associated poses (options.max_diff, offset, tilt_after_s; the
// alignment is ignored). ok false (and *error set if given) when no stamps match.
GravityMetrics ComputeGravityMetrics(const Trajectory& ref, const Trajectory& est,
                                     const EvalOptions& options, std::string* error = nullptr);

// Length of the path through the positions (metres).
double PathLength(const Trajectory& traj);

// evo-style result table, e.g.
//   APE w.r.t. translation part (m)
//   (with SE(3) Umeyama alignment)
//
//          max	0.083008
//         mean	0.016234
//   ... median, min, rmse, sse, std
std::string FormatStatsTable(const std::string& title, const std::string& subtitle,
                             const ErrorStats& stats);
const char* AlignmentDescription(Alignment align);  // "(with SE(3) Umeyama alignment)", ...

// The lines ppf_eval prints after an APE table: tilt median and max over the poses from
// tilt_after_s on, then the final and the largest height error (metres, and the final one in % of
// the reference path).
std::string FormatGravityLines(const GravityMetrics& gravity, double tilt_after_s);

}  // namespace ppf
