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
