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

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/imu_sample.hpp"

namespace ppf {

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
