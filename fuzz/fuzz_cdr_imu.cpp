// Fuzz target: a sensor_msgs/Imu CDR payload, as ppf_node receives it from any DDS peer: CDR
// decode, round trip, and the conversion that screens out non-finite samples and out-of-range
// header stamps.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/cdr.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sensor_msgs::msg::Imu msg;
  std::string error;
  if (!ppf::msgs::DecodeCdr(data, size, &msg, &error)) return 0;

  // Compared bytewise, not with operator==: NaN fields (legal on the wire) never compare equal.
  const std::vector<uint8_t> once = ppf::msgs::EncodeCdr(msg);
  sensor_msgs::msg::Imu msg2;
  if (!ppf::msgs::DecodeCdr(once, &msg2, &error) || ppf::msgs::EncodeCdr(msg2) != once) {
    std::fprintf(stderr, "Imu changed in a decode/encode/decode round trip: %s\n", error.c_str());
    std::abort();
  }

  const auto sample = ppf::bridge::ToImuSample(msg, &error);
  if (sample && msg.header().stamp().nanosec() >= ppf::bridge::kNanosecPerSecond) {
    std::fprintf(stderr, "ToImuSample accepted header.stamp.nanosec %u\n",
                 msg.header().stamp().nanosec());
    std::abort();
  }
  if (sample && (!sample->angular_velocity.allFinite() ||
                 !sample->linear_acceleration.allFinite())) {
    std::fprintf(stderr, "ToImuSample accepted a non-finite sample\n");
    std::abort();
  }
  return 0;
}
