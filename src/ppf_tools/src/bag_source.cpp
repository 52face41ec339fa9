#include "ppf_tools/bag_source.hpp"

#include "ppf_bag/bag.hpp"
#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/cdr.hpp"

namespace ppf::tools {
namespace {

constexpr const char* kCloudType = "sensor_msgs/msg/PointCloud2";
constexpr const char* kImuType = "sensor_msgs/msg/Imu";

std::string Resolve(const bag::BagInfo& info, const std::string& wanted, const char* type,
                    uint64_t* count) {
  for (const auto& t : info.topics) {
    if (wanted.empty() ? t.info.type == type : t.info.name == wanted) {
      if (t.info.type != type) {
        throw bag::BagError("topic " + wanted + " has type " + t.info.type + ", expected " + type);
      }
      if (count) *count = t.message_count;
      return t.info.name;
    }
  }
  throw bag::BagError(wanted.empty() ? std::string("bag has no ") + type + " topic"
                                     : "bag has no topic " + wanted);
}

}  // namespace

BagSourceStats StreamBag(const std::string& bag_path, const BagSourceOptions& options,
                         const BagSourceCallbacks& cb) {
  bag::Reader reader(bag_path);
  BagSourceStats stats;
  stats.points_topic = Resolve(reader.Info(), options.points_topic, kCloudType, &stats.total_scans_in_bag);
  // A bag without IMU messages is a LiDAR-only input (imu_topic stays empty): no IMU topic, or
  // one without messages (ppf_import_pcd without --imu writes such a topic). A named topic that
  // is missing is still an error.
  bool has_imu = !options.imu_topic.empty();
  for (const auto& t : reader.Info().topics) has_imu = has_imu || t.info.type == kImuType;
  uint64_t imu_messages = 0;
  if (has_imu) stats.imu_topic = Resolve(reader.Info(), options.imu_topic, kImuType, &imu_messages);
  if (imu_messages == 0) stats.imu_topic.clear();
  if (stats.imu_topic.empty()) {
    reader.SetTopicFilter({stats.points_topic});
  } else {
    reader.SetTopicFilter({stats.points_topic, stats.imu_topic});
  }
  if (cb.on_topics_resolved) cb.on_topics_resolved(stats);

  bag::Message msg;
  sensor_msgs::msg::PointCloud2 cloud;
  sensor_msgs::msg::Imu imu;
  std::string error;
  auto report = [&](const std::string& what) {
    ++stats.malformed;
    if (cb.on_error) cb.on_error(what);
  };
  while (reader.Next(msg)) {
    if (!stats.imu_topic.empty() && msg.topic == stats.imu_topic) {
      if (!msgs::DecodeCdr(msg.data, &imu, &error)) {
        report("IMU message at " + std::to_string(msg.timestamp_ns) + " ns: " + error);
        continue;
      }
      auto sample = bridge::ToImuSample(imu, &error);
      if (!sample) {
        report("IMU message at " + std::to_string(msg.timestamp_ns) + " ns: " + error);
        continue;
      }
      ++stats.imu;
      if (cb.on_imu) cb.on_imu(*sample);
    } else {
      if (!msgs::DecodeCdr(msg.data, &cloud, &error)) {
        report("PointCloud2 at " + std::to_string(msg.timestamp_ns) + " ns: " + error);
        continue;
      }
      auto view = bridge::ToCloudView(cloud, &error);
      if (!view) {
        report("PointCloud2 at " + std::to_string(msg.timestamp_ns) + " ns: " + error);
        continue;
      }
      ++stats.scans;
      if (cb.on_scan) cb.on_scan(*view);
    }
  }
  return stats;
}

}  // namespace ppf::tools
