// Topic types that carry payloads as bytes, for tools that must not depend on the message type:
// ppf_replay publishes a bag's stored CDR exactly as recorded, ppf_record stores what arrives.
// The DDS type name is the ROS one (e.g. sensor_msgs::msg::dds_::Imu_), so these endpoints match
// typed ones of any vendor. Type information/object are not sent: peers match by name, which is
// what ROS 2 itself relies on.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <fastdds/dds/topic/TopicDataType.hpp>

namespace ppf::dds {

// Whole serialized payload including the 4-byte encapsulation header (as rosbag2 stores it).
struct RawMessage {
  std::vector<uint8_t> payload;
};

class RawPubSubType : public eprosima::fastdds::dds::TopicDataType {
 public:
  explicit RawPubSubType(const std::string& dds_type_name);

  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override;
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override;
  std::function<uint32_t()> getSerializedSizeProvider(void* data) override;
  void* createData() override;
  void deleteData(void* data) override;
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* ihandle,
              bool force_md5 = false) override;
};

}  // namespace ppf::dds
