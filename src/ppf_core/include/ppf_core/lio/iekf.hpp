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

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/residual_provider.hpp"

namespace ppf {

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
