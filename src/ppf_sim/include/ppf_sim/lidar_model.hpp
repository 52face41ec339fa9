// Spinning LiDAR models: beam elevation tables from the public datasheets, horizontal
// resolution, range limits, and the point layout each vendor's ROS driver publishes.
#pragma once

#include <string>
#include <vector>

namespace ppf::sim {

// velodyne_pointcloud (PointXYZIRT): x y z intensity:f32, ring:u16, time:f32 seconds since the
// scan start; unorganized (height 1), dense (no-return beams are left out).
// ouster_ros (Point): x y z intensity:f32, t:u32 ns since the scan start, reflectivity:u16,
// ring:u16, ambient:u16, range:u32 mm; organized (height = beams, width = columns), not dense
// (no-return pixels are kept with x = y = z = 0 and range 0).
enum class PointLayout { kVelodyne, kOuster };

struct LidarModel {
  std::string name;
  // Index = published `ring`. Velodyne drivers number rings from the lowest beam up,
  // Ouster from the top beam down; the tables follow the driver's order.
  std::vector<double> elevation_deg;
  int columns = 1800;     // firings per revolution (horizontal resolution = 360 / columns)
  double rate_hz = 10.0;  // spin rate
  double min_range = 0.5;
  double max_range = 100.0;
  PointLayout layout = PointLayout::kVelodyne;
};

// vlp16, hdl32, hdl64, os1_64, os1_128. Throws std::invalid_argument for other names.
LidarModel GetLidarModel(const std::string& name);
std::vector<std::string> LidarModelNames();

}  // namespace ppf::sim
