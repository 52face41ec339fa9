#include "ppf_bridge/cdr.hpp"

#include <algorithm>
#include <exception>

#include <fastdds/rtps/common/SerializedPayload.h>

namespace ppf::bridge::detail {

using eprosima::fastrtps::rtps::SerializedPayload_t;

bool Serialize(eprosima::fastdds::dds::TopicDataType& type, void* msg, std::vector<uint8_t>* out) {
  SerializedPayload_t payload(type.getSerializedSizeProvider(msg)());
  if (!type.serialize(msg, &payload)) return false;
  out->assign(payload.data, payload.data + payload.length);
  return true;
}

bool Deserialize(eprosima::fastdds::dds::TopicDataType& type, const uint8_t* data, size_t size,
                 void* msg, std::string* error) {
  auto fail = [error](const std::string& why) {
    if (error) *error = why;
    return false;
  };
  if (data == nullptr || size < 4) return fail("CDR payload shorter than its 4-byte header");
  // 00 00 = CDR big endian, 00 01 = CDR little endian (XCDR1, what every ROS 2 distro writes).
  if (data[0] != 0x00 || data[1] > 0x01) {
    return fail("unsupported CDR encapsulation " + std::to_string(data[0]) + "," +
                std::to_string(data[1]));
  }
  if (size > UINT32_MAX) return fail("CDR payload larger than 4 GiB");
  SerializedPayload_t payload(static_cast<uint32_t>(size));
  std::copy(data, data + size, payload.data);
  payload.length = static_cast<uint32_t>(size);
  try {
    if (!type.deserialize(&payload, msg)) return fail("truncated CDR payload");
  } catch (const std::exception& e) {
    // std::bad_alloc from a corrupt sequence length, or a fastcdr exception we do not expect.
    return fail(std::string("malformed CDR payload: ") + e.what());
  }
  return true;
}

}  // namespace ppf::bridge::detail
