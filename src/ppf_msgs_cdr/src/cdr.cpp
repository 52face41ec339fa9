#include "ppf_msgs_cdr/cdr.hpp"

#include "ppf_msgs_cdr/cdr_payload.hpp"

#include <algorithm>

#include <fastdds/rtps/common/SerializedPayload.h>

namespace ppf::msgs::detail {

using eprosima::fastrtps::rtps::SerializedPayload_t;

bool Serialize(eprosima::fastdds::dds::TopicDataType& type, void* msg, std::vector<uint8_t>* out) {
  SerializedPayload_t payload(type.getSerializedSizeProvider(msg)());
  if (!type.serialize(msg, &payload)) return false;
  out->assign(payload.data, payload.data + payload.length);
  return true;
}

bool Deserialize(eprosima::fastdds::dds::TopicDataType& type, const uint8_t* data, size_t size,
                 void* msg, std::string* error) {
  if (size > UINT32_MAX) {
    if (error) *error = "CDR payload larger than 4 GiB";
    return false;
  }
  // One set of acceptance rules for copied and received payloads: see DeserializePayload.
  SerializedPayload_t payload(static_cast<uint32_t>(data != nullptr ? size : 0));
  if (data != nullptr) {
    std::copy(data, data + size, payload.data);
    payload.length = static_cast<uint32_t>(size);
  }
  return DeserializePayload(type, &payload, msg, error);
}

}  // namespace ppf::msgs::detail

namespace ppf::msgs {

bool PeekCloudPointCount(const uint8_t* data, size_t size, uint64_t* points) {
  // Encapsulation (2 bytes kind, 2 options), then the body: Header {stamp {int32 sec, uint32
  // nanosec}, string frame_id (uint32 length with the NUL, characters)}, uint32 height, uint32
  // width. CDR aligns each primitive to its size, counted from the start of the body.
  if (data == nullptr || size < 4 || data[0] != 0x00) return false;
  bool little;
  if (data[1] == 0x01) {
    little = true;
  } else if (data[1] == 0x00) {
    little = false;
  } else {
    return false;
  }
  const uint8_t* body = data + 4;
  const size_t body_size = size - 4;
  auto read_u32 = [&](size_t at, uint32_t* v) {
    if (at > body_size || body_size - at < 4) return false;
    const uint8_t* b = body + at;
    *v = little ? (uint32_t{b[0]} | uint32_t{b[1]} << 8 | uint32_t{b[2]} << 16 | uint32_t{b[3]} << 24)
                : (uint32_t{b[3]} | uint32_t{b[2]} << 8 | uint32_t{b[1]} << 16 | uint32_t{b[0]} << 24);
    return true;
  };
  uint32_t frame_len = 0, height = 0, width = 0;
  if (!read_u32(8, &frame_len) || frame_len > body_size) return false;
  const size_t after_frame = (12 + static_cast<size_t>(frame_len) + 3) & ~size_t{3};
  if (!read_u32(after_frame, &height) || !read_u32(after_frame + 4, &width)) return false;
  *points = uint64_t{height} * width;
  return true;
}

}  // namespace ppf::msgs
