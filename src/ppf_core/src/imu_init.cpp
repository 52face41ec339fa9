#include "ppf_core/imu_init.hpp"

#include <cmath>

#include <Eigen/Geometry>

namespace ppf {

void ImuInitializer::Reset() {
  window_.clear();
  done_ = false;
  refused_for_motion_ = false;
  reason_.clear();
  restart_reason_.clear();
}

ImuInitializer::State ImuInitializer::Add(const ImuSample& sample) {
  if (done_) return State::kDone;
  if (!sample.angular_velocity.allFinite() || !sample.linear_acceleration.allFinite()) {
    return State::kCollecting;  // a broken sample is skipped, not averaged
  }
  if (!window_.empty() && sample.stamp_s < window_.back().stamp_s) {
    window_.clear();
    reason_ = restart_reason_ = "IMU time went backwards during initialization";
    refused_for_motion_ = false;
    window_.push_back(sample);
    return State::kRestarted;
  }
  window_.push_back(sample);
  const double span = window_.back().stamp_s - window_.front().stamp_s;
  if (span < options_.duration_s || static_cast<int>(window_.size()) < options_.min_samples) {
    // Keep saying why the last window was thrown away until initialization succeeds.
    reason_ = "collecting static IMU data" +
              (restart_reason_.empty() ? std::string() : " (" + restart_reason_ + ")");
    return State::kCollecting;
  }

  const double n = static_cast<double>(window_.size());
  Eigen::Vector3d acc_mean = Eigen::Vector3d::Zero(), gyr_mean = Eigen::Vector3d::Zero();
  for (const ImuSample& s : window_) {
    acc_mean += s.linear_acceleration;
    gyr_mean += s.angular_velocity;
  }
  acc_mean /= n;
  gyr_mean /= n;
  const double raw_norm = acc_mean.norm();
  double scale = options_.acc_scale;
  if (!(scale > 0.0)) scale = (raw_norm > 0.5 && raw_norm < 1.5) ? 9.80665 : 1.0;

  double acc_var = 0.0, gyr_var = 0.0;
  for (const ImuSample& s : window_) {
    acc_var += (scale * (s.linear_acceleration - acc_mean)).squaredNorm();
    gyr_var += (s.angular_velocity - gyr_mean).squaredNorm();
  }
  const double acc_std = std::sqrt(acc_var / n), gyr_std = std::sqrt(gyr_var / n);
  const double g_norm = scale * raw_norm;
  if (acc_std > options_.max_acc_std || gyr_std > options_.max_gyro_std || g_norm < 5.0 ||
      g_norm > 15.0) {
    reason_ = "motion during IMU initialization (acc std " + std::to_string(acc_std) +
              " m/s^2, gyro std " + std::to_string(gyr_std) + " rad/s, |g| " +
              std::to_string(g_norm) + "): restarting";
    restart_reason_ = reason_;
    refused_for_motion_ = true;
    window_.clear();
    return State::kRestarted;
  }

  const double g_expected = options_.gravity > 0.0 ? options_.gravity : 9.80665;
  const bool turning = gyr_mean.norm() > options_.max_gyro_bias;
  const bool accelerating = std::abs(g_norm - g_expected) > options_.max_gravity_error;
  if (turning || accelerating) {
    std::string why;
    if (turning) {
      why = "gyro mean " + std::to_string(gyr_mean.norm()) + " rad/s > max_gyro_bias " +
            std::to_string(options_.max_gyro_bias);
    }
    if (accelerating) {
      why += std::string(turning ? ", " : "") + "|a| " + std::to_string(g_norm) +
             " m/s^2 differs from gravity " + std::to_string(g_expected) + " by more than " +
             std::to_string(options_.max_gravity_error);
    }
    reason_ = restart_reason_ = "steady motion during IMU initialization (" + why + "): restarting";
    refused_for_motion_ = true;
    window_.clear();
    return State::kRestarted;
  }

  acc_scale_ = scale;
  gyro_bias_ = gyr_mean;
  const double g = options_.gravity > 0.0 ? options_.gravity : g_norm;
  // At rest the accelerometer measures -g in the body frame: rotate it onto +z.
  R_world_imu_ =
      Eigen::Quaterniond::FromTwoVectors(acc_mean.normalized(), Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  gravity_world_ = Eigen::Vector3d(0.0, 0.0, -g);
  stamp_s_ = window_.back().stamp_s;
  done_ = true;
  reason_.clear();
  restart_reason_.clear();
  window_.clear();
  return State::kDone;
}

}  // namespace ppf
