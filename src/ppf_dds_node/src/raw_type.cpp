#include "ppf_dds_node/raw_type.hpp"

#include <cstring>

#include <fastdds/rtps/common/SerializedPayload.h>

namespace ppf::dds {

using eprosima::fastrtps::rtps::SerializedPayload_t;

RawPubSubType::RawPubSubType(const std::string& dds_type_name) {
  setName(dds_type_name.c_str());
  // Initial buffer size only: the history grows buffers on demand (PREALLOCATED_WITH_REALLOC),
  // so this must not be the largest message, just a typical small one.
  m_typeSize = 4096;
  m_isGetKeyDefined = false;
  // ROS 2 types have no key.
}

bool RawPubSubType::serialize(void* data, SerializedPayload_t* payload) {
  const auto* msg = static_cast<const RawMessage*>(data);
  if (msg->payload.size() < 4 || msg->payload.size() > UINT32_MAX) return false;
  const uint32_t size = static_cast<uint32_t>(msg->payload.size());
  // Fast DDS sized the payload with getSerializedSizeProvider; never grow a pool-owned buffer.
  if (payload->max_size < size) return false;
  std::memcpy(payload->data, msg->payload.data(), size);
  payload->length = size;
  // The encapsulation is part of the stored bytes; keep Fast DDS's field consistent with them.
  payload->encapsulation = msg->payload[1] == 0x01 ? 0x01 : 0x00;
  return true;
}

bool RawPubSubType::deserialize(SerializedPayload_t* payload, void* data) {
  auto* msg = static_cast<RawMessage*>(data);
  msg->payload.assign(payload->data, payload->data + payload->length);
  return true;
}

std::function<uint32_t()> RawPubSubType::getSerializedSizeProvider(void* data) {
  return [data]() { return static_cast<uint32_t>(static_cast<RawMessage*>(data)->payload.size()); };
}

void* RawPubSubType::createData() { return new RawMessage(); }

void RawPubSubType::deleteData(void* data) { delete static_cast<RawMessage*>(data); }

bool RawPubSubType::getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) {
  return false;
}

}  // namespace ppf::dds
