// ROS 1 message serialization -> ROS 2 CDR, for the message types the odometry consumes.
//
// A ROS 1 bag stores messages in ROS 1 serialization (little endian, no alignment, Header with a
// seq field, time as uint32 sec + uint32 nsec). Every consumer in this project decodes ROS 2 CDR,
// so the ROS 1 storage converts on read and presents the messages under their ROS 2 type names.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ppf::bag::detail {

enum class Ros1Conversion {
  kPassThrough,  // bytes returned as stored, type keeps its ROS 1 name, format "ros1"
  kPointCloud2,  // sensor_msgs/PointCloud2 -> sensor_msgs/msg/PointCloud2 (CDR)
  kImu,          // sensor_msgs/Imu -> sensor_msgs/msg/Imu (CDR)
  kLivoxCustom,  // livox_ros_driver(2)/CustomMsg -> sensor_msgs/msg/PointCloud2 (CDR)
};

// Chooses the conversion for a ROS 1 connection from its type and md5sum. A known type name
// with a different md5sum is a different definition (a fork, an older version): it is passed
// through rather than decoded with the wrong layout.
Ros1Conversion Ros1ConversionFor(const std::string& ros1_type, const std::string& md5sum);

// ROS 2 type name ("sensor_msgs/msg/PointCloud2"), or the ROS 1 name for kPassThrough.
std::string Ros1PresentedType(Ros1Conversion conversion, const std::string& ros1_type);

// Converts one ROS 1 serialized message. On malformed input returns false and sets `error`
// (what was wrong and at which byte of the message); `out` is then unspecified.
bool ConvertRos1Message(Ros1Conversion conversion, const uint8_t* data, size_t size,
                        std::vector<uint8_t>* out, std::string* error);

// The PointCloud2 layout a Livox CustomMsg becomes (documented in src/ppf_bag/README.md):
// x, y, z, intensity float32 at 0/4/8/12, tag uint8 at 16, line uint8 at 17, offset_time
// uint32 at 20 (ns after the cloud's header stamp), point_step 24.
constexpr uint32_t kLivoxPointStep = 24;

}  // namespace ppf::bag::detail
