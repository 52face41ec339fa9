// Reader-side topic type that decodes through ppf_bridge (DecodeCdrPayload: DecodeCdr's checks,
// straight from the received payload, no extra copy of a multi-MB cloud) and never rejects a sample
// inside Fast DDS: a malformed payload arrives as {valid = false, error}, so the node counts and
// logs it (a generated type would make Fast DDS drop it without telling us).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>

#include <fastdds/rtps/common/SerializedPayload.h>
#include <fastdds/dds/topic/TopicDataType.hpp>

#include "ppf_msgs_cdr/cdr_payload.hpp"
#include "ppf_msgs_cdr/msg_traits.hpp"

namespace ppf::dds {

template <typename MsgT>
struct Validated {
  MsgT msg;
  bool valid = false;
  std::string error;
  size_t payload_size = 0;
  // The type's gate refused the payload before decoding (error says why): msg is untouched.
  bool refused = false;
};

template <typename MsgT>
class ValidatingPubSubType : public eprosima::fastdds::dds::TopicDataType {
 public:
  // Sees the raw payload (encapsulation header included) before it is decoded; a non-empty
  // reason refuses the sample undecoded (Validated::refused), so e.g. an oversized cloud costs no
  // copy of its data. Runs on Fast DDS's receive thread: it must not block or take our locks.
  using Gate = std::function<std::string(const uint8_t* data, size_t size)>;

  explicit ValidatingPubSubType(Gate gate = nullptr) : gate_(std::move(gate)) {
    setName(msgs::MsgTraits<MsgT>::kDdsName);
    m_typeSize = 4096;  // initial buffer only; histories grow on demand
    m_isGetKeyDefined = false;
  }

  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override {
    typename msgs::MsgTraits<MsgT>::PubSubType generated;
    return generated.serialize(&static_cast<Validated<MsgT>*>(data)->msg, payload);
  }

  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    auto* out = static_cast<Validated<MsgT>*>(data);
    out->payload_size = payload->length;
    out->error.clear();
    out->refused = false;
    if (gate_) {
      std::string reason = gate_(payload->data, payload->length);
      if (!reason.empty()) {
        out->refused = true;
        out->valid = false;
        out->error = std::move(reason);
        return true;
      }
    }
    out->valid = msgs::DecodeCdrPayload(payload, &out->msg, &out->error);
    return true;  // delivered either way; the listener decides
  }

  std::function<uint32_t()> getSerializedSizeProvider(void* data) override {
    typename msgs::MsgTraits<MsgT>::PubSubType generated;
    return generated.getSerializedSizeProvider(&static_cast<Validated<MsgT>*>(data)->msg);
  }

  void* createData() override { return new Validated<MsgT>(); }
  void deleteData(void* data) override { delete static_cast<Validated<MsgT>*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }

 private:
  Gate gate_;
};

}  // namespace ppf::dds
