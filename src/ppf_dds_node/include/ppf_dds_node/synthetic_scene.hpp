// A static box room seen by a spinning multi-beam LiDAR, plus a resting IMU: enough for the core
// to initialize and register, in the driver message types the node's tests and ppf_latency_bench
// publish (HDL-64-sized clouds, where only the node's own overhead is of interest). The room is
// made of the simulator's scene primitives and cast with its scene (ppf_sim_gen); what is here
// is the beam pattern and the message packing.
#pragma once

#include <cstdint>

#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::dds {

struct SyntheticLidar {
  int rings = 64;
  int columns = 2048;  // 64 x 2048 = 131072 points (HDL-64 at 10 Hz: ~130k)
  double min_elevation_deg = -24.9;
  double max_elevation_deg = 2.0;
  double scan_period_s = 0.1;
};

// Fields x, y, z, intensity (float32), t (float32, seconds since the header stamp = scan start),
// ring (uint16); point_step 24. Deterministic in `stamp_ns`.
sensor_msgs::msg::PointCloud2 MakeRoomScan(const SyntheticLidar& lidar, int64_t stamp_ns);

// At rest, gravity-aligned: acc (0, 0, 9.81) m/s^2, gyro 0 (tiny deterministic noise).
sensor_msgs::msg::Imu MakeRestingImu(int64_t stamp_ns, uint64_t seq);

}  // namespace ppf::dds
