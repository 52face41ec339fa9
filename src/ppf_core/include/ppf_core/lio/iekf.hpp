// Iterated error-state Kalman filter update on SO(3) x R^12 x S2 (state in imu_propagation.hpp).
//
// Each iteration asks every ResidualProvider for point-to-plane rows at the current estimate,
// linearises r = n . (R (R_il p + t_il) + p) + offset about it and solves the MAP problem
//   min |x (-) x_prior|^2_P + sum_i w_i r_i^2 / sigma^2
// in information form (17x17, the measurement touches only rotation and position). Stops when the
// correction is below the convergence thresholds or after max_iterations; the posterior covariance
// is (P^-1 + H^T R^-1 H)^-1 at the final linearisation point.
//
// Degeneracy: eigenvalues of the rotation and translation blocks of J^T J (unweighted, so they
// count "points worth of constraint" along each eigen-direction; rotation ones scale with range^2).
// A direction below its threshold is degenerate: the measurement part of the correction is removed
// along it, so the IMU prediction is kept there, and the result reports it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/residual_provider.hpp"

namespace ppf {

struct IekfOptions {
  int max_iterations = 4;
  double convergence_rot_rad = 1e-4;  // |dtheta| below this ...
  double convergence_trans_m = 1e-3;  // ... and |dp| below this: converged
  // Metres: the noise of one point-to-plane row (weight 1) as the update counts it. Far above one
  // return's range noise on purpose: a scan's rows are not independent measurements. Neighbouring
  // rows share their map plane's (or skeleton patch's) fitting error, and every row shares the
  // scan's de-skew error, so a few thousand rows carry far less information than a few thousand
  // independent ones. Counted as independent at the range noise, they made the LiDAR so sure of
  // roll and pitch that each scan overruled the gyro and the accelerometer, and whatever error
  // the rows shared tilted the world away from gravity (issue 11, worst in fast hand-held PPF
  // runs); counted at this level the IMU keeps the tilt, and position is still the LiDAR's.
  double laser_point_std = 0.3;
  // Radians: the part of a row's noise that grows with the point's range. A far point is matched
  // to a plane fitted from neighbours as far apart as the beams are there, so its row's error
  // grows with range and, through its lever arm, turns the map about a horizontal axis (issue 11).
  // Row variance = laser_point_std^2 + (laser_angular_std * range)^2; 0 = range-independent.
  // Scaled with laser_point_std (same ratio), so near and far rows keep their relative weights.
  double laser_angular_std = 0.05;
  // Metres; from the second iteration on, rows whose residual at the current estimate exceeds
  // this are dropped (0 = off). The providers' own gates must be wide enough for the prediction's
  // error (a fast turn, a bumpy start), but at those widths wrong associations (a road point
  // matched to a kerb, a facade to its neighbour) pass at full weight, and they are not symmetric
  // about the vehicle: they turn the map away from gravity. Once the first iteration has brought
  // the estimate near, true matches sit within a few laser sigmas, and only they shape the
  // posterior. Not while the map is young: built from the static start's few rings, it fits
  // planes whose true matches lie farther out while the platform first moves away.
  double refined_gate = 0.1;
  double refined_gate_after_s = 3.0;  // seconds after the map's first scan
  int min_rows = 20;                  // fewer rows: skip the update, keep the prediction
  // J^T J eigenvalue (points) per direction below which the direction is degenerate. 10 rows of
  // 3 cm noise still pin it to ~1 cm per scan; 30 (the first default) threw that away: PPF on the
  // 60 s hand-held indoor VLP-16 corridor (the sandwich layer discards door-frame points) was
  // degenerate along the corridor in 285 of 590 scans, APE 98 mm; with 10: 5 scans, 17 mm. kNN
  // there: 13.3 mm either way.
  double degeneracy_min_eig_translation = 10.0;
  double degeneracy_min_eig_rotation = 300.0;  // J^T J eigenvalue (points * m^2)
  // Metres from the LiDAR beyond which points give no residual (0 = no limit); they are still
  // mapped. Far rows fit planes to sparse, grazing returns and their errors act through long
  // lever arms: on the simulated drives they tilted the map away from gravity (issue 11's note).
  double residual_max_range = 0.0;
};

struct IekfReport {
  int iterations = 0;
  bool converged = false;
  bool skipped = false;  // too few rows: prediction kept
  int num_rows = 0;      // rows of the last iteration
  std::vector<int> rows_per_provider;
  bool degenerate = false;
  std::string degenerate_reason;  // e.g. "translation along (0.00 1.00 0.00): eig 3.1 < 30"
  Eigen::Vector3d eig_rotation = Eigen::Vector3d::Zero();     // ascending
  Eigen::Vector3d eig_translation = Eigen::Vector3d::Zero();  // ascending
  double residuals_ms = 0.0;                                  // summed over iterations
  double update_ms = 0.0;
};

// Runs the iterated update on *state (prior = *state on entry). Providers must have had
// BeginScan() called. Never throws.
IekfReport IekfUpdate(const IekfOptions& options, const Eigen::Isometry3d& T_imu_lidar,
                      const std::vector<ResidualProvider*>& providers, NavState* state);

}  // namespace ppf
