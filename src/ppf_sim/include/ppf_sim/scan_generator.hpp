// Casts one LiDAR sweep into a scene along the ground-truth trajectory.
//
// Every firing column has its own time; the sensor pose is evaluated at that time, so scans
// carry the same motion distortion as a real spinning sensor. Points are expressed in the
// LiDAR frame at their own firing time (what a driver publishes).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "ppf_sim/cloud_buffer.hpp"
#include "ppf_sim/lidar_model.hpp"
#include "ppf_sim/scene.hpp"
#include "ppf_sim/trajectory.hpp"

namespace ppf::sim {

struct ScanOptions {
  double range_noise = 0.02;  // m, 1 sigma, Gaussian
  double dropout = 0.005;     // probability that a return is lost at random
  uint64_t seed = 1;
  Eigen::Isometry3d T_imu_lidar = Eigen::Isometry3d::Identity();
  int64_t start_ns = 0;       // absolute time of sim time 0
  std::string frame_id = "lidar";
  double max_range = 0.0;     // 0 = model default
  // Other drivers' time conventions (velodyne layout only), for testing time-field detection:
  // kDriverDefault: `time` f32 s after the header stamp; kNone: no per-point time at all;
  // kAbsoluteF64: `timestamp` f64 absolute seconds (Hesai-style).
  enum class TimeField { kDriverDefault, kNone, kAbsoluteF64 } time_field = TimeField::kDriverDefault;
  // Header stamp at the scan end (ROS 1 velodyne style): relative times are then negative.
  bool stamp_at_end = false;
};

// Default T_imu_lidar: LiDAR 0.2 m ahead, 0.05 m left and 0.15 m above the IMU, rotated by
// roll 1.0, pitch -1.5, yaw 2.0 deg (a realistic, slightly imperfect mount). Part of the
// generator library so that in-process users (no bag, no calibration.yaml) get the same mount.
Eigen::Isometry3d DefaultImuLidarExtrinsic();

class ScanGenerator {
 public:
  ScanGenerator(const Scene& scene, const Trajectory& traj, LidarModel model, ScanOptions opt);

  // Scan k covers sim time [k / rate, (k + 1) / rate). Thread-parallel, deterministic.
  CloudBuffer Generate(int k) const;
  int NumScans(double duration) const;
  double period() const { return 1.0 / model_.rate_hz; }
  const LidarModel& model() const { return model_; }

  // Azimuth (rad, sensor frame, x forward, y left) of column c. Columns start behind the
  // sensor (azimuth +pi) and advance clockwise seen from above, like the real sensors.
  double ColumnAzimuth(int c) const;

 private:
  const Scene& scene_;
  const Trajectory& traj_;
  LidarModel model_;
  ScanOptions opt_;
  std::vector<double> cos_el_, sin_el_;
};

}  // namespace ppf::sim
