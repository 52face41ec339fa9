// CDR payloads of ROS 2 messages: what DDS puts on the wire and rosbag2 stores, i.e. a 4-byte
// encapsulation header (00 01 00 00 = little-endian CDR) followed by the classic CDR body.
//
// Decoding never throws: a malformed payload from a bag or a foreign driver is reported with a
// reason and the caller keeps running.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "ppf_msgs_cdr/msg_traits.hpp"

namespace ppf::msgs {

namespace detail {
bool Serialize(eprosima::fastdds::dds::TopicDataType& type, void* msg, std::vector<uint8_t>* out);
bool Deserialize(eprosima::fastdds::dds::TopicDataType& type, const uint8_t* data, size_t size,
                 void* msg, std::string* error);
}  // namespace detail

// Full payload of `msg`, encapsulation header included, unpadded.
template <typename MsgT>
std::vector<uint8_t> EncodeCdr(const MsgT& msg) {
  typename MsgTraits<MsgT>::PubSubType type;
  std::vector<uint8_t> out;
  // The generated serializer takes a non-const pointer but does not modify the message.
  detail::Serialize(type, const_cast<MsgT*>(&msg), &out);
  return out;
}

// Decodes a payload as received from DDS or read from a bag (ROS pads payloads to a multiple of
// 4 bytes; both forms are accepted). Returns false and fills `error` for an unknown
// encapsulation or a truncated/malformed body.
template <typename MsgT>
bool DecodeCdr(const uint8_t* data, size_t size, MsgT* out, std::string* error = nullptr) {
  typename MsgTraits<MsgT>::PubSubType type;
  return detail::Deserialize(type, data, size, out, error);
}

template <typename MsgT>
bool DecodeCdr(const std::vector<uint8_t>& payload, MsgT* out, std::string* error = nullptr) {
  return DecodeCdr(payload.data(), payload.size(), out, error);
}

// The point count (height x width) a sensor_msgs/PointCloud2 payload declares, read from its first
// bytes without decoding it, so a receiver can refuse an oversized cloud before copying its data.
// False if the payload is too short for its header or its encapsulation is unknown; the full
// decode then says what is wrong.
bool PeekCloudPointCount(const uint8_t* data, size_t size, uint64_t* points);

}  // namespace ppf::msgs
