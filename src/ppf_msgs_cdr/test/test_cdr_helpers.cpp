// The CDR helpers and stamp conversions every package that touches a message shares.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "ppf_msgs_cdr/cdr.hpp"
#include "ppf_msgs_cdr/testing/sample_cloud.hpp"
#include "ppf_msgs_cdr/time.hpp"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::msgs {
namespace {

using test_util::MakeCloud;

TEST(Cdr, EncodeDecodeRoundTrip) {
  auto cloud = MakeCloud(1000);
  auto payload = EncodeCdr(cloud);
  ASSERT_GT(payload.size(), 20000u);
  EXPECT_EQ(payload[0], 0x00);
  EXPECT_EQ(payload[1], 0x01);
  sensor_msgs::msg::PointCloud2 back;
  std::string error;
  ASSERT_TRUE(DecodeCdr(payload, &back, &error)) << error;
  EXPECT_TRUE(back == cloud);
}

TEST(Cdr, RejectsTruncatedPayload) {
  auto payload = EncodeCdr(MakeCloud(100));
  payload.resize(payload.size() / 2);
  sensor_msgs::msg::PointCloud2 back;
  std::string error;
  EXPECT_FALSE(DecodeCdr(payload, &back, &error));
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
}

TEST(Cdr, RejectsUnknownEncapsulationAndTinyPayload) {
  auto payload = EncodeCdr(MakeCloud(3));
  payload[1] = 0x03;  // PL_CDR_LE: not what ROS 2 sends for topics
  sensor_msgs::msg::PointCloud2 back;
  std::string error;
  EXPECT_FALSE(DecodeCdr(payload, &back, &error));
  EXPECT_NE(error.find("encapsulation"), std::string::npos) << error;
  std::vector<uint8_t> tiny = {0x00, 0x01};
  EXPECT_FALSE(DecodeCdr(tiny, &back, &error));
}

TEST(Cdr, RejectsAbsurdSequenceLengthWithoutCrashing) {
  auto payload = EncodeCdr(MakeCloud(2));
  // The fields sequence length sits after the header (stamp 8 + string 4+9 -> pad) and
  // height/width. Corrupt every 4-byte word in turn to a huge count: decoding must fail cleanly,
  // never crash.
  for (size_t off = 4; off + 4 <= payload.size(); off += 4) {
    auto bad = payload;
    bad[off] = bad[off + 1] = bad[off + 2] = 0xff;
    bad[off + 3] = 0x7f;
    sensor_msgs::msg::PointCloud2 back;
    std::string error;
    if (!DecodeCdr(bad, &back, &error)) {
      EXPECT_FALSE(error.empty());
    }
  }
}

TEST(Time, ConversionsKeepNanosecondsAndFloorNegative) {
  auto t = TimeFromNanoseconds(1700000000123456789LL);
  EXPECT_EQ(t.sec(), 1700000000);
  EXPECT_EQ(t.nanosec(), 123456789u);
  EXPECT_EQ(ToNanoseconds(t), 1700000000123456789LL);
  auto neg = TimeFromNanoseconds(-1);
  EXPECT_EQ(neg.sec(), -1);
  EXPECT_EQ(neg.nanosec(), 999999999u);
  EXPECT_NEAR(ToSeconds(TimeFromSeconds(12.5)), 12.5, 1e-12);
}

}  // namespace
}  // namespace ppf::msgs
