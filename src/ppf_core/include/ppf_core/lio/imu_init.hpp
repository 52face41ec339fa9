// IMU initialization from a static start.
//
// Collects samples for ImuInitOptions::duration_s (default 1.0 s, and at least min_samples = 20,
// so IMUs from 20 Hz up initialize within the duration; 50 Hz or more is recommended). While
// collecting, the spread of the accelerometer norm and of the gyro is watched: if the robot moves
// (std above max_acc_std / max_gyro_std), the window is discarded and collection restarts; the
// facade then reports Status::kInitializing with the reason "motion during IMU initialization".
// A window without spread is refused as well when its gyro mean exceeds max_gyro_bias (a steady
// turn) or its accelerometer norm is off gravity by more than max_gravity_error (a steady
// acceleration): reason "steady motion during IMU initialization".
//
// Results: gyro bias = mean gyro; gravity magnitude = mean accelerometer norm (times acc_scale);
// the accelerometer unit is detected: a mean norm in [0.5, 1.5] means the driver reports in g and
// acc_scale becomes 9.80665 (override with ImuInitOptions::acc_scale > 0). The world frame is
// gravity aligned: R_world_imu is the smallest rotation taking the mean specific force to +z, so
// the world z axis points up, gravity is (0, 0, -|g|), and yaw is 0 (no rotation about z).
// Accelerometer bias starts at 0 (it is not separable from tilt while static).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ppf_core/imu_sample.hpp"

namespace ppf {

struct ImuInitOptions {
  double duration_s = 1.0;    // static time needed
  int min_samples = 20;       // and at least this many samples
  double max_acc_std = 0.3;   // m/s^2 (after unit scaling); above: "moving", restart
  double max_gyro_std = 0.05; // rad/s; above: "moving", restart
  double acc_scale = 0.0;     // multiply raw accelerometer readings; 0 = detect (1 or 9.80665)
  double gravity = 0.0;       // gravity magnitude m/s^2; 0 = use the measured norm
  // A steady motion has no spread and still is not rest: a constant turn shows as a gyro mean far
  // above any plausible bias (taking it for one bends every later heading), and an acceleration
  // or the centripetal part of a fast turn as an accelerometer norm off gravity (taking it for
  // gravity tilts the world). Checked against `gravity` (or 9.80665 if that is 0).
  double max_gyro_bias = 0.05;      // rad/s (~3 deg/s: above MEMS turn-on biases)
  double max_gravity_error = 0.3;   // m/s^2 between the mean accelerometer norm and gravity
  // Moving start (moving_start.hpp, run by the facade): when a window is refused for motion,
  // gravity, velocity and gyro bias are estimated from moving_start_window_s of scans registered
  // without the IMU meanwhile and the IMU, instead of waiting for rest.
  bool moving_start = true;
  double moving_start_window_s = 1.5;
  double moving_start_max_gravity_error = 0.5;  // m/s^2: |g| of the free estimate vs gravity
};

class ImuInitializer {
 public:
  enum class State { kCollecting, kDone, kRestarted };

  explicit ImuInitializer(const ImuInitOptions& options = ImuInitOptions()) : options_(options) {}

  // Feeds one raw sample. kRestarted: motion detected, the window was cleared (see reason()).
  State Add(const ImuSample& sample);

  bool done() const { return done_; }
  // The last window was refused because the IMU moved (spread or steady motion), not for a
  // broken stream.
  bool refused_for_motion() const { return refused_for_motion_; }
  const std::string& reason() const { return reason_; }
  void Reset();

  // Valid once done().
  Eigen::Matrix3d R_world_imu() const { return R_world_imu_; }
  Eigen::Vector3d gyro_bias() const { return gyro_bias_; }
  Eigen::Vector3d gravity_world() const { return gravity_world_; }
  double acc_scale() const { return acc_scale_; }
  double stamp_s() const { return stamp_s_; }  // time of the last sample used

 private:
  // Accepts the static window: the world's z is the measured "up", the gyro mean the bias.
  void Finish(const Eigen::Vector3d& acc_mean, const Eigen::Vector3d& gyr_mean, double scale,
              double g_norm);

  ImuInitOptions options_;
  std::vector<ImuSample> window_;
  bool done_ = false;
  bool refused_for_motion_ = false;
  std::string reason_;
  std::string restart_reason_;
  Eigen::Matrix3d R_world_imu_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_world_ = Eigen::Vector3d(0, 0, -9.80665);
  double acc_scale_ = 1.0;
  double stamp_s_ = 0.0;
};

}  // namespace ppf
