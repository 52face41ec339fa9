// Moving-start initialization: gravity, velocity and gyro bias from LiDAR poses and the IMU.
//
// When the IMU never shows a window at rest (ImuInitializer refuses it for motion), the facade
// registers the first scans without the IMU (docs/behaviour.md, "Moving start") and hands the
// IMU poses of those scans, in the frame of the map they built, to EstimateMovingStart. With the
// IMU preintegrated from the first pose's time t0 to each later pose's time tj (dt = tj - t0):
//
//   R_j = R_0 dR_0j(b_g)                            -> gyro bias (Gauss-Newton, 3 unknowns)
//   p_j = p_0 + v_0 dt + 1/2 g dt^2 + R_0 dp_0j      -> v_0 and g (linear, 6 unknowns)
//
// Every equation is anchored at the first pose: over a window of about a second the gravity
// term (about 5 m) dwarfs the registration error, which a scan-to-scan pairing (0.05 m of
// gravity term per 0.1 s) would not. The accelerometer bias is not separable from gravity here
// either (it stays 0, as after a static start); the magnitude of g is fixed to the known one once
// its direction is estimated, and the unconstrained magnitude is the consistency check.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/imu_sample.hpp"

namespace ppf {

// IMU pose (T_map_imu) at a registered scan's time.
struct MovingStartPose {
  double t = 0.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
};

struct MovingStartOptions {
  double gravity = 9.80665;        // m/s^2, magnitude g is fixed to
  double acc_scale = 0.0;          // 0 = detect from the mean accelerometer norm (1 or 9.80665)
  double max_gravity_error = 0.5;  // m/s^2 between the unconstrained |g| and `gravity`
  double max_gyro_bias = 0.05;     // rad/s; a larger estimate means the registration is off
  // m; the position equations' RMS after the fit. The fit spreads a slipped registration over
  // velocity and gravity (the dt and dt^2 columns are nearly parallel over a second), so its
  // size is checked rather than trusted to show in |g|.
  double max_rms_residual = 0.1;
};

struct MovingStartEstimate {
  bool ok = false;
  std::string reason;                                     // why not ok
  Eigen::Vector3d gravity_map = Eigen::Vector3d::Zero();  // |g| = options.gravity
  double gravity_norm_free = 0.0;                         // magnitude of the unconstrained estimate
  double gravity_sigma = 0.0;  // m/s^2, 1 sigma of the unconstrained estimate (residuals)
  Eigen::Vector3d velocity_map = Eigen::Vector3d::Zero();  // at the last pose's time
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  double acc_scale = 1.0;
  double rms_residual = 0.0;  // m, of the position equations after the fit
};

struct Preintegrated {
  Eigen::Matrix3d dR = Eigen::Matrix3d::Identity();
  Eigen::Vector3d dv = Eigen::Vector3d::Zero();
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
};

// Midpoint preintegration of bias-corrected raw samples (time ordered) from t0 to t1 in the
// body frame at t0, without gravity.
Preintegrated Preintegrate(const std::vector<ImuSample>& imu, double t0, double t1,
                           const Eigen::Vector3d& gyro_bias, double acc_scale);

// Needs at least 3 poses spanning > 0.3 s and IMU covering them.
MovingStartEstimate EstimateMovingStart(const std::vector<ImuSample>& imu,
                                        const std::vector<MovingStartPose>& poses,
                                        const MovingStartOptions& options);

}  // namespace ppf
