// Odometry at the IMU's rate between scans: the filter's posterior at a scan end, propagated
// with every later IMU sample exactly as the filter predicts the next scan (the same midpoint
// integration and process noise, lio/imu_propagation.hpp), so a controller gets a pose per IMU
// sample instead of one per scan, with the covariance growing until the next scan corrects it.
//
// A scan's result comes only once IMU coverage has reached the scan end, and the registration
// takes time: by then samples after the scan's stamp have been seen already. The class keeps the
// recent samples and, on each new posterior, re-propagates through those after its stamp; later
// samples continue from there. It touches no LioPpf: a caller may run it on another thread than
// the core's (it is not thread-safe itself).
//
// Frames are the results' (lio_ppf.hpp): the gravity-aligned world of ScanResult::T_world_imu,
// the IMU body frame. The filter's gravity (map frame) is carried into that world with
// ScanResult::T_world_map, where it points straight down.
#pragma once

#include <cstddef>
#include <deque>
#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/config.hpp"
#include "ppf_core/imu_sample.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_core/result_types.hpp"

namespace ppf {

class ImuRateOdometry {
 public:
  struct Options {
    ImuNoise noise;  // the filter's process noise (Config imu.noise), so the covariance grows alike
    // Multiplies raw accelerations (imu.init.acc_scale); 0 = detect as the initializer does
    // (a mean accelerometer norm near 1 means the driver reports in g).
    double acc_scale = 0.0;
    // Seconds of samples kept for re-propagation: longer than a scan takes from its end to its
    // result (the IMU wait plus the registration).
    double buffer_s = 1.0;
    // A gap between samples longer than this (or a stamp this far back: a new timeline) ends the
    // propagation until the next posterior: holding one sample across it would be a guess.
    double max_gap_s = 0.1;
  };

  // The propagated state at one IMU sample.
  struct State {
    double stamp_s = 0.0;  // the sample's stamp
    Eigen::Isometry3d T_world_imu = Eigen::Isometry3d::Identity();
    Eigen::Vector3d velocity_world = Eigen::Vector3d::Zero();
    Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // IMU frame, gyro bias removed
    // Error-state order of imu_propagation.hpp (ScanResult::covariance): rotation body frame,
    // position and velocity world frame.
    StateCov covariance = StateCov::Zero();
  };

  struct Counters {
    size_t late = 0;    // samples not newer than the newest one: dropped
    size_t breaks = 0;  // gaps or jumps that ended the propagation
  };

  ImuRateOdometry() : ImuRateOdometry(Options()) {}
  explicit ImuRateOdometry(const Options& options);

  // A new posterior. A result without a pose, or registered without the IMU (LiDAR-only, IMU
  // lost), ends the propagation instead (false): its biases and gravity do not describe the IMU.
  // Otherwise the state is set from it and propagated through the kept samples after its stamp.
  bool Reset(const ScanResult& result);

  // The core started over (or the output is stopped): no state until the next Reset. The kept
  // samples stay if `keep_samples` (the stream goes on), else they go too (a new timeline).
  void Invalidate(bool keep_samples = true);

  // One IMU sample (raw, as the core gets it). Returns the state propagated to its stamp, or
  // nothing: no posterior yet, the sample is not newer than the newest one, or a gap broke the
  // propagation.
  std::optional<State> AddImu(const ImuSample& sample);

  bool valid() const { return valid_; }
  double acc_scale() const { return acc_scale_; }
  const Counters& counters() const { return counters_; }

 private:
  // Propagates the state from its stamp to `t_end` (a kept sample's stamp) with the kept
  // samples; false (and invalid) if the posterior lies more than max_gap_s before all of them.
  bool PropagateTo(double t_end);
  void DetectAccScale();

  Options options_;
  double acc_scale_ = 0.0;  // 0 until detected
  std::deque<ImuSample> samples_;
  bool valid_ = false;
  NavState state_;  // the filter's state (imu_propagation.hpp), in the results' world frame
  Counters counters_;
};

}  // namespace ppf
