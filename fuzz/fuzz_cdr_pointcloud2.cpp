// Fuzz target: a sensor_msgs/PointCloud2 CDR payload, as ppf_node receives it from any DDS peer
// and ppf_offline reads it from a bag, through every step before the filter: CDR decode, the
// re-encode the recorder and registered_points output use, the view (which must refuse an
// out-of-range header stamp), the layout check and the per-point time decoder (with and without
// a forced time convention).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "ppf_bridge/convert.hpp"
#include "ppf_core/lio/time_field.hpp"
#include "ppf_msgs_cdr/cdr.hpp"

namespace {

// ROS 2 strings are C strings: every rmw (and Fast CDR's serializer, which uses strlen) ends
// them at the first NUL, while the decoder keeps the bytes after one. Compared as ROS sees them.
std::string AsCString(const std::string& s) { return s.substr(0, s.find('\0')); }

sensor_msgs::msg::PointCloud2 WithCStrings(sensor_msgs::msg::PointCloud2 msg) {
  msg.header().frame_id(AsCString(msg.header().frame_id()));
  for (auto& f : msg.fields()) f.name(AsCString(f.name()));
  return msg;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  sensor_msgs::msg::PointCloud2 msg;
  std::string error;
  if (!ppf::msgs::DecodeCdr(data, size, &msg, &error)) return 0;

  // Whatever decodes must survive a round trip unchanged: a difference would mean the node
  // records or republishes something other than what it received.
  const std::vector<uint8_t> again = ppf::msgs::EncodeCdr(msg);
  sensor_msgs::msg::PointCloud2 msg2;
  if (!ppf::msgs::DecodeCdr(again, &msg2, &error) || !(msg2 == WithCStrings(msg)) ||
      ppf::msgs::EncodeCdr(msg2) != again) {
    std::fprintf(stderr, "PointCloud2 changed in a decode/encode/decode round trip: %s\n",
                 error.c_str());
    std::abort();
  }

  const auto view = ppf::bridge::ToCloudView(msg, &error);
  if (!view) return 0;
  // An out-of-range stamp would reach the filter as a time seconds off.
  if (msg.header().stamp().nanosec() >= ppf::bridge::kNanosecPerSecond) {
    std::fprintf(stderr, "ToCloudView accepted header.stamp.nanosec %u\n",
                 msg.header().stamp().nanosec());
    std::abort();
  }
  ppf::DecodedScan scan;
  ppf::TimeFieldDecoder detecting;
  detecting.Decode(*view, &scan, &error);
  detecting.Decode(*view, &scan, &error);  // the already-detected path
  ppf::TimeFieldOptions forced;
  forced.field = "t";
  forced.reference = ppf::TimeReference::kAbsolute;
  forced.stamp = ppf::StampPosition::kEnd;
  ppf::TimeFieldDecoder(forced).Decode(*view, &scan, &error);
  return 0;
}
