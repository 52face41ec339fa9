// One complete run: world, IMU, scans, rosbag2 output and ground-truth files.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "ppf_sim/bag_output.hpp"
#include "ppf_sim/imu_simulator.hpp"
#include "ppf_sim/scan_generator.hpp"
#include "ppf_sim/world.hpp"

namespace ppf::sim {

// A stretch of time [t, t + length) of sim time.
struct TimeWindow {
  double t = 0.0;
  double length = 0.0;
  bool Contains(double x) const { return x >= t && x < t + length; }
  bool Overlaps(double a, double b) const { return a < t + length && b > t; }
};

// Faults of the sensors and the path that the filter's models do not contain, with exact ground
// truth: the ground-truth file always covers the whole run at every IMU sample time.
struct Disturbances {
  std::vector<Jolt> jolts;              // steps of the true path the IMU does not see
  std::vector<TimeWindow> imu_gaps;     // no IMU sample in these windows (the LiDAR goes on)
  std::vector<TimeWindow> silences;     // neither IMU samples nor sweeps overlapping them
  double gyro_range = 0.0;              // rad/s; > 0: each gyro axis saturates at +-this
  bool any() const {
    return !jolts.empty() || !imu_gaps.empty() || !silences.empty() || gyro_range > 0.0;
  }
};

struct SimConfig {
  WorldOptions world;
  std::string lidar = "hdl64";
  ScanOptions scan;              // seed and start_ns are taken from this config's fields below
  double imu_rate = 200.0;
  ImuNoise imu_noise;
  double gravity = 9.81;
  std::string imu_frame = "imu";
  BagOutputOptions bag;
  std::string out_dir;
  int64_t start_ns = 1700000000LL * 1000000000LL;  // absolute time of sim time 0
  uint64_t seed = 1;
  Disturbances disturbances;

  SimConfig();
};

// DefaultImuLidarExtrinsic() (the simulated mount) is declared in scan_generator.hpp.

struct SimSummary {
  int scans = 0;
  uint64_t points = 0;
  int imu_samples = 0;
  uint64_t bytes = 0;
  double seconds_world = 0, seconds_imu = 0, seconds_scans = 0, seconds_write = 0,
         seconds_total = 0;
};

// Writes `out_dir` (rosbag2 directory + groundtruth.tum + calibration.yaml + imu_bias.csv).
// Progress and a timing table go to `log`.
SimSummary RunSimulation(const SimConfig& cfg, std::ostream& log);

}  // namespace ppf::sim
