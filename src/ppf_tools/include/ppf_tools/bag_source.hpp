// Reads a rosbag2 bag (sqlite3 or MCAP) as a time-ordered stream of core inputs: the offline
// runner and benchmarks use it; the DDS node has its own (live) source.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "ppf_core/cloud_view.hpp"
#include "ppf_core/imu_sample.hpp"

namespace ppf::tools {

struct BagSourceOptions {
  std::string points_topic;  // empty: the first sensor_msgs/msg/PointCloud2 topic of the bag
  std::string imu_topic;     // empty: the first sensor_msgs/msg/Imu topic of the bag
};

struct BagSourceStats {
  uint64_t scans = 0;
  uint64_t imu = 0;
  uint64_t malformed = 0;  // messages that failed to decode (reported through on_error)
  uint64_t total_scans_in_bag = 0;
  std::string points_topic;
  std::string imu_topic;  // empty: the bag has no IMU topic (LiDAR-only input)
};

struct BagSourceCallbacks {
  std::function<void(const ImuSample&)> on_imu;
  std::function<void(const CloudView&)> on_scan;  // the view is valid during the call only
  std::function<void(const std::string&)> on_error;
  std::function<void(const BagSourceStats&)> on_topics_resolved;  // before the first message
};

// Streams the whole bag. Throws ppf::bag::BagError for an unreadable bag or when the topics
// cannot be resolved; a single malformed message is reported and skipped (counted).
BagSourceStats StreamBag(const std::string& bag_path, const BagSourceOptions& options,
                         const BagSourceCallbacks& callbacks);

}  // namespace ppf::tools
