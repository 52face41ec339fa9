// Wire-format tests: the generated types must produce the exact bytes ROS 2 produces, keep the
// ROS 2 DDS type names, and survive a CDR round trip field by field.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include <fastdds/rtps/common/SerializedPayload.h>

#include "builtin_interfaces/msg/TimePubSubTypes.h"
#include "geometry_msgs/msg/PointPubSubTypes.h"
#include "geometry_msgs/msg/PosePubSubTypes.h"
#include "geometry_msgs/msg/PoseStampedPubSubTypes.h"
#include "geometry_msgs/msg/PoseWithCovariancePubSubTypes.h"
#include "geometry_msgs/msg/QuaternionPubSubTypes.h"
#include "geometry_msgs/msg/TransformPubSubTypes.h"
#include "geometry_msgs/msg/TransformStampedPubSubTypes.h"
#include "geometry_msgs/msg/TwistPubSubTypes.h"
#include "geometry_msgs/msg/TwistWithCovariancePubSubTypes.h"
#include "geometry_msgs/msg/Vector3PubSubTypes.h"
#include "nav_msgs/msg/OdometryPubSubTypes.h"
#include "nav_msgs/msg/PathPubSubTypes.h"
#include "ppf_msgs/msg/SkeletonPlaneArrayPubSubTypes.h"
#include "ppf_msgs/msg/SkeletonPlanePubSubTypes.h"
#include "sensor_msgs/msg/ImuPubSubTypes.h"
#include "sensor_msgs/msg/PointCloud2PubSubTypes.h"
#include "sensor_msgs/msg/PointFieldPubSubTypes.h"
#include "std_msgs/msg/HeaderPubSubTypes.h"
#include "tf2_msgs/msg/TFMessagePubSubTypes.h"

namespace {

using eprosima::fastrtps::rtps::SerializedPayload_t;

template <typename PubSubT, typename MsgT>
std::vector<uint8_t> Serialize(MsgT& msg) {
  PubSubT type;
  SerializedPayload_t payload(type.getSerializedSizeProvider(&msg)());
  EXPECT_TRUE(type.serialize(&msg, &payload));
  return std::vector<uint8_t>(payload.data, payload.data + payload.length);
}

template <typename PubSubT, typename MsgT>
MsgT Deserialize(const std::vector<uint8_t>& bytes) {
  PubSubT type;
  SerializedPayload_t payload(static_cast<uint32_t>(bytes.size()));
  std::copy(bytes.begin(), bytes.end(), payload.data);
  payload.length = static_cast<uint32_t>(bytes.size());
  MsgT msg;
  EXPECT_TRUE(type.deserialize(&payload, &msg));
  return msg;
}

std_msgs::msg::Header MakeHeader(int32_t sec, uint32_t nsec, const std::string& frame) {
  std_msgs::msg::Header h;
  h.stamp().sec(sec);
  h.stamp().nanosec(nsec);
  h.frame_id(frame);
  return h;
}

sensor_msgs::msg::PointCloud2 InteropExampleCloud() {
  // The example of ROS2-INTEROP.md ("Wire format").
  sensor_msgs::msg::PointCloud2 c;
  c.header(MakeHeader(1, 2, "lidar"));
  c.height(1);
  c.width(2);
  sensor_msgs::msg::PointField f;
  f.name("x");
  f.offset(0);
  f.datatype(7);
  f.count(1);
  c.fields().push_back(f);
  c.is_bigendian(false);
  c.point_step(4);
  c.row_step(8);
  c.data({0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40});
  c.is_dense(true);
  return c;
}

TEST(CdrBytes, PointCloud2MatchesRos2Example) {
  const std::vector<uint8_t> expected = {
      0x00, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x00,
      0x00, 0x00, 0x6c, 0x69, 0x64, 0x61, 0x72, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
      0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x78, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x07, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x08, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x01};
  auto cloud = InteropExampleCloud();
  auto bytes = Serialize<sensor_msgs::msg::PointCloud2PubSubType>(cloud);
  ASSERT_GE(bytes.size(), expected.size());
  EXPECT_EQ(std::vector<uint8_t>(bytes.begin(), bytes.begin() + expected.size()), expected);
  // Anything past the message itself may only be alignment padding (ROS pads to 4 bytes).
  EXPECT_LE(bytes.size(), (expected.size() + 3) / 4 * 4);
}

TEST(CdrBytes, ReaderAcceptsPayloadWithAndWithoutRosPadding) {
  auto cloud = InteropExampleCloud();
  auto bytes = Serialize<sensor_msgs::msg::PointCloud2PubSubType>(cloud);
  ASSERT_EQ(bytes.size(), 81u);  // exact, unpadded
  EXPECT_EQ((Deserialize<sensor_msgs::msg::PointCloud2PubSubType, sensor_msgs::msg::PointCloud2>(bytes)), cloud);
  bytes.resize(84, 0);  // padded to a multiple of 4, as rclcpp writes it
  EXPECT_EQ((Deserialize<sensor_msgs::msg::PointCloud2PubSubType, sensor_msgs::msg::PointCloud2>(bytes)), cloud);
}

TEST(CdrBytes, TruncatedPayloadIsRejected) {
  auto cloud = InteropExampleCloud();
  auto bytes = Serialize<sensor_msgs::msg::PointCloud2PubSubType>(cloud);
  bytes.resize(40);  // cut inside the fields sequence
  sensor_msgs::msg::PointCloud2PubSubType type;
  SerializedPayload_t payload(static_cast<uint32_t>(bytes.size()));
  std::copy(bytes.begin(), bytes.end(), payload.data);
  payload.length = static_cast<uint32_t>(bytes.size());
  sensor_msgs::msg::PointCloud2 out;
  EXPECT_FALSE(type.deserialize(&payload, &out));
}

TEST(CdrBytes, ImuLayoutIsRos2) {
  sensor_msgs::msg::Imu imu;
  imu.header(MakeHeader(3, 4, "imu"));
  imu.orientation().w(1.0);
  imu.angular_velocity().z(0.5);
  imu.linear_acceleration().z(9.81);
  auto bytes = Serialize<sensor_msgs::msg::ImuPubSubType>(imu);
  // 4 encapsulation + header (4+4 stamp, 4 len + "imu\0" = 8) = 20, pad to 8-byte alignment of the
  // CDR body (offset 16 -> 16, already aligned), then 4 + 9 + 3 + 9 + 3 + 9 doubles = 37 doubles.
  EXPECT_EQ(bytes.size(), 4u + 16u + 37u * 8u);
  EXPECT_EQ(bytes[0], 0x00);
  EXPECT_EQ(bytes[1], 0x01);
}

TEST(TypeNames, AreTheRos2DdsNames) {
  EXPECT_STREQ(builtin_interfaces::msg::TimePubSubType().getName(), "builtin_interfaces::msg::dds_::Time_");
  EXPECT_STREQ(std_msgs::msg::HeaderPubSubType().getName(), "std_msgs::msg::dds_::Header_");
  EXPECT_STREQ(sensor_msgs::msg::PointFieldPubSubType().getName(), "sensor_msgs::msg::dds_::PointField_");
  EXPECT_STREQ(sensor_msgs::msg::PointCloud2PubSubType().getName(), "sensor_msgs::msg::dds_::PointCloud2_");
  EXPECT_STREQ(sensor_msgs::msg::ImuPubSubType().getName(), "sensor_msgs::msg::dds_::Imu_");
  EXPECT_STREQ(geometry_msgs::msg::PointPubSubType().getName(), "geometry_msgs::msg::dds_::Point_");
  EXPECT_STREQ(geometry_msgs::msg::Vector3PubSubType().getName(), "geometry_msgs::msg::dds_::Vector3_");
  EXPECT_STREQ(geometry_msgs::msg::QuaternionPubSubType().getName(), "geometry_msgs::msg::dds_::Quaternion_");
  EXPECT_STREQ(geometry_msgs::msg::PosePubSubType().getName(), "geometry_msgs::msg::dds_::Pose_");
  EXPECT_STREQ(geometry_msgs::msg::PoseWithCovariancePubSubType().getName(),
               "geometry_msgs::msg::dds_::PoseWithCovariance_");
  EXPECT_STREQ(geometry_msgs::msg::TwistPubSubType().getName(), "geometry_msgs::msg::dds_::Twist_");
  EXPECT_STREQ(geometry_msgs::msg::TwistWithCovariancePubSubType().getName(),
               "geometry_msgs::msg::dds_::TwistWithCovariance_");
  EXPECT_STREQ(geometry_msgs::msg::PoseStampedPubSubType().getName(), "geometry_msgs::msg::dds_::PoseStamped_");
  EXPECT_STREQ(geometry_msgs::msg::TransformPubSubType().getName(), "geometry_msgs::msg::dds_::Transform_");
  EXPECT_STREQ(geometry_msgs::msg::TransformStampedPubSubType().getName(),
               "geometry_msgs::msg::dds_::TransformStamped_");
  EXPECT_STREQ(nav_msgs::msg::OdometryPubSubType().getName(), "nav_msgs::msg::dds_::Odometry_");
  EXPECT_STREQ(nav_msgs::msg::PathPubSubType().getName(), "nav_msgs::msg::dds_::Path_");
  EXPECT_STREQ(tf2_msgs::msg::TFMessagePubSubType().getName(), "tf2_msgs::msg::dds_::TFMessage_");
  EXPECT_STREQ(ppf_msgs::msg::SkeletonPlanePubSubType().getName(), "ppf_msgs::msg::dds_::SkeletonPlane_");
  EXPECT_STREQ(ppf_msgs::msg::SkeletonPlaneArrayPubSubType().getName(),
               "ppf_msgs::msg::dds_::SkeletonPlaneArray_");
}

// Round trips: every field set to a distinct non-default value, so a dropped or swapped field fails.
template <typename PubSubT, typename MsgT>
void ExpectRoundTrip(MsgT msg) {
  auto bytes = Serialize<PubSubT>(msg);
  ASSERT_GE(bytes.size(), 4u);
  EXPECT_EQ(bytes[1], 0x01) << "little-endian CDR encapsulation expected";
  MsgT back = Deserialize<PubSubT, MsgT>(bytes);
  EXPECT_TRUE(back == msg);
  // A default-constructed message must differ, otherwise the test proves nothing.
  EXPECT_FALSE(MsgT() == msg);
}

geometry_msgs::msg::Vector3 V(double x, double y, double z) {
  geometry_msgs::msg::Vector3 v;
  v.x(x);
  v.y(y);
  v.z(z);
  return v;
}
geometry_msgs::msg::Point P(double x, double y, double z) {
  geometry_msgs::msg::Point p;
  p.x(x);
  p.y(y);
  p.z(z);
  return p;
}
geometry_msgs::msg::Quaternion Q(double x, double y, double z, double w) {
  geometry_msgs::msg::Quaternion q;
  q.x(x);
  q.y(y);
  q.z(z);
  q.w(w);
  return q;
}
geometry_msgs::msg::Pose MakePose(double k) {
  geometry_msgs::msg::Pose p;
  p.position(P(k, k + 1, k + 2));
  p.orientation(Q(0.1 * k, 0.2, 0.3, 0.9));
  return p;
}
geometry_msgs::msg::TransformStamped MakeTf(int i) {
  geometry_msgs::msg::TransformStamped t;
  t.header(MakeHeader(10 + i, 20, "odom"));
  t.child_frame_id("base_link_" + std::to_string(i));
  t.transform().translation(V(1, 2, 3 + i));
  t.transform().rotation(Q(0, 0, 0.38268343, 0.92387953));
  return t;
}

TEST(CdrRoundTrip, EveryType) {
  builtin_interfaces::msg::Time time;
  time.sec(-5);
  time.nanosec(999999999u);
  ExpectRoundTrip<builtin_interfaces::msg::TimePubSubType>(time);
  ExpectRoundTrip<std_msgs::msg::HeaderPubSubType>(MakeHeader(7, 8, "map"));

  sensor_msgs::msg::PointField field;
  field.name("intensity");
  field.offset(12);
  field.datatype(7);
  field.count(1);
  ExpectRoundTrip<sensor_msgs::msg::PointFieldPubSubType>(field);
  ExpectRoundTrip<sensor_msgs::msg::PointCloud2PubSubType>(InteropExampleCloud());

  sensor_msgs::msg::Imu imu;
  imu.header(MakeHeader(1, 5, "imu_link"));
  imu.orientation(Q(0, 0, 0, 1));
  for (size_t i = 0; i < 9; ++i) {
    imu.orientation_covariance()[i] = -1.0 * static_cast<double>(i);
    imu.angular_velocity_covariance()[i] = 0.01 * static_cast<double>(i);
    imu.linear_acceleration_covariance()[i] = 0.02 * static_cast<double>(i);
  }
  imu.angular_velocity(V(0.1, -0.2, 0.3));
  imu.linear_acceleration(V(0.5, 0.0, 9.81));
  ExpectRoundTrip<sensor_msgs::msg::ImuPubSubType>(imu);

  ExpectRoundTrip<geometry_msgs::msg::PointPubSubType>(P(1, -2, 3));
  ExpectRoundTrip<geometry_msgs::msg::Vector3PubSubType>(V(-1, 2, -3));
  ExpectRoundTrip<geometry_msgs::msg::QuaternionPubSubType>(Q(0.5, 0.5, 0.5, 0.5));
  ExpectRoundTrip<geometry_msgs::msg::PosePubSubType>(MakePose(2));

  geometry_msgs::msg::PoseWithCovariance pwc;
  pwc.pose(MakePose(3));
  for (size_t i = 0; i < 36; ++i) pwc.covariance()[i] = static_cast<double>(i) * 1e-3;
  ExpectRoundTrip<geometry_msgs::msg::PoseWithCovariancePubSubType>(pwc);

  geometry_msgs::msg::Twist twist;
  twist.linear(V(1, 0, 0));
  twist.angular(V(0, 0, 0.2));
  ExpectRoundTrip<geometry_msgs::msg::TwistPubSubType>(twist);
  geometry_msgs::msg::TwistWithCovariance twc;
  twc.twist(twist);
  twc.covariance()[35] = 4.0;
  ExpectRoundTrip<geometry_msgs::msg::TwistWithCovariancePubSubType>(twc);

  geometry_msgs::msg::PoseStamped ps;
  ps.header(MakeHeader(4, 4, "odom"));
  ps.pose(MakePose(4));
  ExpectRoundTrip<geometry_msgs::msg::PoseStampedPubSubType>(ps);
  geometry_msgs::msg::Transform tf;
  tf.translation(V(4, 5, 6));
  tf.rotation(Q(0, 1, 0, 0));
  ExpectRoundTrip<geometry_msgs::msg::TransformPubSubType>(tf);
  ExpectRoundTrip<geometry_msgs::msg::TransformStampedPubSubType>(MakeTf(1));

  nav_msgs::msg::Odometry odom;
  odom.header(MakeHeader(9, 10, "odom"));
  odom.child_frame_id("base_link");
  odom.pose(pwc);
  odom.twist(twc);
  ExpectRoundTrip<nav_msgs::msg::OdometryPubSubType>(odom);

  nav_msgs::msg::Path path;
  path.header(MakeHeader(11, 12, "odom"));
  for (int i = 0; i < 3; ++i) {
    ps.pose(MakePose(i));
    path.poses().push_back(ps);
  }
  ExpectRoundTrip<nav_msgs::msg::PathPubSubType>(path);

  tf2_msgs::msg::TFMessage tfm;
  tfm.transforms().push_back(MakeTf(0));
  tfm.transforms().push_back(MakeTf(1));
  ExpectRoundTrip<tf2_msgs::msg::TFMessagePubSubType>(tfm);

  ppf_msgs::msg::SkeletonPlane plane;
  plane.id(42);
  plane.age(7);
  plane.normal(V(0, 0, 1));
  plane.offset(-1.5);
  plane.centroid(P(3, 4, 1.5));
  plane.orientation(Q(0, 0, 0, 1));
  plane.size(V(20, 10, 0.03));
  plane.inlier_count(1234);
  plane.incremental(true);
  ExpectRoundTrip<ppf_msgs::msg::SkeletonPlanePubSubType>(plane);
  ppf_msgs::msg::SkeletonPlaneArray planes;
  planes.header(MakeHeader(13, 14, "odom"));
  planes.planes().push_back(plane);
  plane.id(43);
  plane.incremental(false);
  planes.planes().push_back(plane);
  ExpectRoundTrip<ppf_msgs::msg::SkeletonPlaneArrayPubSubType>(planes);
}

}  // namespace
