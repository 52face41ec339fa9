#include "ppf_msgs_cdr/cdr_payload.hpp"

#include <exception>

namespace ppf::msgs::detail {

bool DeserializePayload(eprosima::fastdds::dds::TopicDataType& type,
                        eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* msg,
                        std::string* error) {
  auto fail = [error](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  // 00 00 / 00 01 = classic CDR (XCDR1) big / little endian: what every ROS 2 distro writes.
  if (payload == nullptr || payload->data == nullptr || payload->length < 4) {
    return fail("CDR payload shorter than its 4-byte header");
  }
  const uint8_t* data = payload->data;
  if (data[0] != 0x00 || data[1] > 0x01) {
    return fail("unsupported CDR encapsulation " + std::to_string(data[0]) + "," +
                std::to_string(data[1]));
  }
  try {
    if (!type.deserialize(payload, msg)) return fail("truncated CDR payload");
  } catch (const std::exception& e) {
    return fail(std::string("malformed CDR payload: ") + e.what());
  }
  return true;
}

}  // namespace ppf::msgs::detail
