#include "ppf_core/lio/imu_init.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace ppf {

void ImuInitializer::Reset() {
  window_.clear();
  done_ = false;
  refused_for_motion_ = false;
  reason_.clear();
  restart_reason_.clear();
}

namespace {

// Mean and spread of a static window, with the accelerometer scale (g units or m/s^2) decided.
struct WindowStats {
  Eigen::Vector3d acc_mean = Eigen::Vector3d::Zero();  // raw units
  Eigen::Vector3d gyr_mean = Eigen::Vector3d::Zero();
  double scale = 1.0;    // raw accelerometer units to m/s^2
  double acc_std = 0.0;  // m/s^2
  double gyr_std = 0.0;  // rad/s
  double g_norm = 0.0;   // |mean acceleration| in m/s^2
};

WindowStats ComputeWindowStats(const std::vector<ImuSample>& window, double acc_scale_option) {
  WindowStats w;
  const double n = static_cast<double>(window.size());
  for (const ImuSample& s : window) {
    w.acc_mean += s.linear_acceleration;
    w.gyr_mean += s.angular_velocity;
  }
  w.acc_mean /= n;
  w.gyr_mean /= n;
  const double raw_norm = w.acc_mean.norm();
  w.scale = acc_scale_option;
  // Not set: a mean near 1 is an accelerometer reporting in g.
  if (!(w.scale > 0.0)) w.scale = (raw_norm > 0.5 && raw_norm < 1.5) ? 9.80665 : 1.0;
  double acc_var = 0.0, gyr_var = 0.0;
  for (const ImuSample& s : window) {
    acc_var += (w.scale * (s.linear_acceleration - w.acc_mean)).squaredNorm();
    gyr_var += (s.angular_velocity - w.gyr_mean).squaredNorm();
  }
  w.acc_std = std::sqrt(acc_var / n);
  w.gyr_std = std::sqrt(gyr_var / n);
  w.g_norm = w.scale * raw_norm;
  return w;
}

// Why the window cannot be a static one: spread (shaking) or an implausible |g|. Empty if it can.
std::string SpreadRefusal(const WindowStats& w, const ImuInitOptions& o) {
  const bool moving =
      w.acc_std > o.max_acc_std || w.gyr_std > o.max_gyro_std || w.g_norm < 5.0 || w.g_norm > 15.0;
  if (!moving) return {};
  return "motion during IMU initialization (acc std " + std::to_string(w.acc_std) +
         " m/s^2, gyro std " + std::to_string(w.gyr_std) + " rad/s, |g| " +
         std::to_string(w.g_norm) + "): restarting";
}

// Why a smooth window is still not at rest: a steady turn (gyro mean above any plausible bias) or
// steady acceleration (|a| off gravity). Empty if it is at rest.
std::string SteadyMotionRefusal(const WindowStats& w, const ImuInitOptions& o) {
  const double g_expected = o.gravity > 0.0 ? o.gravity : 9.80665;
  const bool turning = w.gyr_mean.norm() > o.max_gyro_bias;
  const bool accelerating = std::abs(w.g_norm - g_expected) > o.max_gravity_error;
  if (!turning && !accelerating) return {};
  std::string why;
  if (turning) {
    why = "gyro mean " + std::to_string(w.gyr_mean.norm()) + " rad/s > max_gyro_bias " +
          std::to_string(o.max_gyro_bias);
  }
  if (accelerating) {
    why += std::string(turning ? ", " : "") + "|a| " + std::to_string(w.g_norm) +
           " m/s^2 differs from gravity " + std::to_string(g_expected) + " by more than " +
           std::to_string(o.max_gravity_error);
  }
  return "steady motion during IMU initialization (" + why + "): restarting";
}

}  // namespace

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

  const WindowStats w = ComputeWindowStats(window_, options_.acc_scale);
  std::string refusal = SpreadRefusal(w, options_);
  if (refusal.empty()) refusal = SteadyMotionRefusal(w, options_);
  if (!refusal.empty()) {
    reason_ = restart_reason_ = refusal;
    refused_for_motion_ = true;
    window_.clear();
    return State::kRestarted;
  }
  Finish(w.acc_mean, w.gyr_mean, w.scale, w.g_norm);
  return State::kDone;
}

void ImuInitializer::Finish(const Eigen::Vector3d& acc_mean, const Eigen::Vector3d& gyr_mean,
                            double scale, double g_norm) {
  acc_scale_ = scale;
  gyro_bias_ = gyr_mean;
  const double g = options_.gravity > 0.0 ? options_.gravity : g_norm;
  // At rest the accelerometer measures -g in the body frame: rotate it onto +z.
  R_world_imu_ = Eigen::Quaterniond::FromTwoVectors(acc_mean.normalized(), Eigen::Vector3d::UnitZ())
                     .toRotationMatrix();
  gravity_world_ = Eigen::Vector3d(0.0, 0.0, -g);
  stamp_s_ = window_.back().stamp_s;
  done_ = true;
  reason_.clear();
  restart_reason_.clear();
  window_.clear();
}

}  // namespace ppf
