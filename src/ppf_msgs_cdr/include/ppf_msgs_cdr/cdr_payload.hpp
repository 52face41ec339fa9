// Decoding straight from the Fast DDS payload a TopicDataType::deserialize receives, with the
// same checks and never-throw contract as DecodeCdr (cdr.hpp), but without DecodeCdr's copy of
// the whole payload: for multi-megabyte clouds decoded in a DDS listener (ppf_dds_node).
#pragma once

#include <string>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "ppf_msgs_cdr/msg_traits.hpp"

namespace ppf::msgs {

namespace detail {
bool DeserializePayload(eprosima::fastdds::dds::TopicDataType& type,
                        eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* msg,
                        std::string* error);
}  // namespace detail

// `payload` holds the encapsulation header and the CDR body, as received; it is only read.
template <typename MsgT>
bool DecodeCdrPayload(eprosima::fastrtps::rtps::SerializedPayload_t* payload, MsgT* out,
                      std::string* error = nullptr) {
  typename MsgTraits<MsgT>::PubSubType type;
  return detail::DeserializePayload(type, payload, out, error);
}

}  // namespace ppf::msgs
