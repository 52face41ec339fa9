#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ppf_bridge/cdr.hpp"
#include "ppf_bridge/convert.hpp"

namespace ppf::bridge {
namespace {

sensor_msgs::msg::PointCloud2 MakeCloud(uint32_t n) {
  sensor_msgs::msg::PointCloud2 c;
  c.header().stamp(TimeFromNanoseconds(1700000000123456789LL));
  c.header().frame_id("velodyne");
  c.height(1);
  c.width(n);
  const char* names[] = {"x", "y", "z", "intensity"};
  for (uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::msg::PointField f;
    f.name(names[i]);
    f.offset(4 * i);
    f.datatype(7);
    f.count(1);
    c.fields().push_back(f);
  }
  sensor_msgs::msg::PointField t;
  t.name("t");
  t.offset(16);
  t.datatype(6);
  t.count(1);
  c.fields().push_back(t);
  c.point_step(20);
  c.row_step(20 * n);
  c.data().resize(20 * n);
  for (uint32_t i = 0; i < 20 * n; ++i) c.data()[i] = static_cast<uint8_t>(i * 7);
  c.is_dense(true);
  return c;
}

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
  // The fields sequence length sits after the header (stamp 8 + string 4+9 -> pad) and height/width.
  // Corrupt every 4-byte word in turn to a huge count: decoding must fail cleanly, never crash.
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

TEST(Convert, TimeConversionsKeepNanosecondsAndFloorNegative) {
  auto t = TimeFromNanoseconds(1700000000123456789LL);
  EXPECT_EQ(t.sec(), 1700000000);
  EXPECT_EQ(t.nanosec(), 123456789u);
  EXPECT_EQ(ToNanoseconds(t), 1700000000123456789LL);
  auto neg = TimeFromNanoseconds(-1);
  EXPECT_EQ(neg.sec(), -1);
  EXPECT_EQ(neg.nanosec(), 999999999u);
  EXPECT_NEAR(ToSeconds(TimeFromSeconds(12.5)), 12.5, 1e-12);
}

TEST(Convert, CloudViewPointsIntoMessageWithoutCopy) {
  auto cloud = MakeCloud(10);
  auto view = ToCloudView(cloud);
  ASSERT_TRUE(view.has_value());
  EXPECT_EQ(view->data, cloud.data().data());
  EXPECT_EQ(view->size, 200u);
  EXPECT_EQ(view->width, 10u);
  EXPECT_EQ(view->point_step, 20u);
  ASSERT_EQ(view->fields.size(), 5u);
  EXPECT_EQ(view->fields[4].name, "t");
  EXPECT_EQ(view->fields[4].type, FieldType::kUint32);
  EXPECT_EQ(view->frame_id, "velodyne");
  EXPECT_NEAR(view->stamp_s, 1700000000.123456789, 1e-6);
}

TEST(Convert, CloudWithUnknownDatatypeIsRejected) {
  auto cloud = MakeCloud(1);
  cloud.fields()[2].datatype(9);
  std::string error;
  EXPECT_FALSE(ToCloudView(cloud, &error).has_value());
  EXPECT_NE(error.find("'z'"), std::string::npos) << error;
}

TEST(Convert, ImuRoundTripAndNanRejected) {
  ImuSample s;
  s.stamp_s = 100.25;
  s.angular_velocity = {0.1, -0.2, 0.3};
  s.linear_acceleration = {0.0, 0.5, 9.81};
  auto msg = ToImuMsg(s, "imu_link");
  EXPECT_EQ(msg.header().frame_id(), "imu_link");
  EXPECT_EQ(msg.orientation_covariance()[0], -1.0);
  auto back = ToImuSample(msg);
  ASSERT_TRUE(back.has_value());
  EXPECT_NEAR(back->stamp_s, 100.25, 1e-9);
  EXPECT_TRUE(back->angular_velocity.isApprox(s.angular_velocity));
  EXPECT_TRUE(back->linear_acceleration.isApprox(s.linear_acceleration));
  msg.linear_acceleration().y(std::numeric_limits<double>::quiet_NaN());
  std::string error;
  EXPECT_FALSE(ToImuSample(msg, &error).has_value());
  EXPECT_FALSE(error.empty());
}

}  // namespace
}  // namespace ppf::bridge
