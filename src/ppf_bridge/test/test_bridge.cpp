#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ppf_bridge/convert.hpp"
#include "ppf_bridge/skeleton_planes.hpp"
#include "ppf_msgs_cdr/testing/sample_cloud.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::bridge {
namespace {

using msgs::test_util::MakeCloud;

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

// Layouts a reader cannot trust, each refused with the reason (hostile inputs).
TEST(Convert, InconsistentCloudLayoutsAreRejectedWithTheReason) {
  auto expect_rejected = [](const sensor_msgs::msg::PointCloud2& c, const std::string& reason) {
    std::string error;
    EXPECT_FALSE(ToCloudView(c, &error).has_value()) << reason;
    EXPECT_NE(error.find(reason), std::string::npos) << error;
  };
  auto c = MakeCloud(10);
  c.fields()[3].name("x");
  expect_rejected(c, "duplicate field 'x'");
  c = MakeCloud(10);
  c.fields()[3].offset(18);  // intensity (float32) would end at byte 22 of a 20-byte point
  expect_rejected(c, "field 'intensity' (offset 18, 4 bytes) lies beyond point_step 20");
  c = MakeCloud(10);
  c.fields()[4].count(2);  // t (uint32) x2 from offset 16
  expect_rejected(c, "field 't' (offset 16, 8 bytes) lies beyond point_step 20");
  c = MakeCloud(10);
  c.data().resize(c.data().size() + 20);
  expect_rejected(c, "size mismatch: 220 bytes of data, header declares 200");
  c = MakeCloud(10);
  c.data().resize(c.data().size() - 1);
  expect_rejected(c, "size mismatch: 199 bytes for 10x1 points of 20 bytes (need 200)");
  c = MakeCloud(10);
  c.row_step(100);
  expect_rejected(c, "row_step 100 < width * point_step 200");
  c = MakeCloud(10);
  c.is_bigendian(true);
  expect_rejected(c, "big-endian");
  c = MakeCloud(10);
  c.fields().erase(c.fields().begin() + 1);
  expect_rejected(c, "lacks an x, y or z field");
  // Organized (2 rows of 5) and empty clouds are fine.
  c = MakeCloud(10);
  c.height(2);
  c.width(5);
  c.row_step(100);
  EXPECT_TRUE(ToCloudView(c).has_value());
  c = MakeCloud(0);
  EXPECT_TRUE(ToCloudView(c).has_value());
}

// A header stamp whose nanosecond part is a second or more is no time at all (read as it
// stands it moved the scan seconds ahead): refused, cloud and IMU alike, with the value.
TEST(Convert, StampWithNanosecOutOfRangeIsRefused) {
  auto c = MakeCloud(10);
  builtin_interfaces::msg::Time t = c.header().stamp();
  t.nanosec(999999999u);
  c.header().stamp(t);
  std::string error;
  EXPECT_TRUE(ToCloudView(c, &error).has_value()) << error;
  t.nanosec(kNanosecPerSecond);
  c.header().stamp(t);
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("header.stamp.nanosec 1000000000 is out of range"), std::string::npos)
      << error;
  t.nanosec(4000000000u);
  c.header().stamp(t);
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("nanosec 4000000000"), std::string::npos) << error;

  ImuSample s;
  s.stamp_s = 100.25;
  s.angular_velocity = {0.1, -0.2, 0.3};
  s.linear_acceleration = {0.0, 0.5, 9.81};
  auto msg = ToImuMsg(s, "imu");
  t = msg.header().stamp();
  t.nanosec(4000000000u);
  msg.header().stamp(t);
  EXPECT_FALSE(ToImuSample(msg, &error).has_value());
  EXPECT_NE(error.find("IMU sample's header.stamp.nanosec 4000000000 is out of range"),
            std::string::npos)
      << error;
}

// row_step 0 (published by some drivers for unorganized clouds) is width * point_step, and the
// data must then match exactly; a non-zero row_step below a row is refused.
TEST(Convert, RowStepZeroIsReadAsWidthTimesPointStep) {
  auto c = MakeCloud(10);
  c.row_step(0);
  std::string error;
  auto view = ToCloudView(c, &error);
  ASSERT_TRUE(view.has_value()) << error;
  EXPECT_EQ(view->size, 200u);
  c.data().resize(220);
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("header declares 200 (height 1 x row_step 200)"), std::string::npos)
      << error;
  c = MakeCloud(10);
  c.row_step(199);
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("row_step 199 < width * point_step 200"), std::string::npos) << error;
}

// A cloud with no field table says so (not "lacks x, y or z"); thousands of extra fields are a
// valid layout, checked for duplicates without quadratic cost.
TEST(Convert, NoFieldsRefusedManyFieldsAccepted) {
  auto c = MakeCloud(10);
  c.fields().clear();
  std::string error;
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("cloud declares no fields"), std::string::npos) << error;
  c = MakeCloud(10);
  for (int i = 0; i < 5000; ++i) {
    sensor_msgs::msg::PointField f;
    f.name("extra_" + std::to_string(i));
    f.offset(static_cast<uint32_t>(i % 20));
    f.datatype(2);
    f.count(1);
    c.fields().push_back(f);
  }
  auto view = ToCloudView(c, &error);
  ASSERT_TRUE(view.has_value()) << error;
  EXPECT_EQ(view->fields.size(), 5005u);
  c.fields()[4000].name("extra_17");
  EXPECT_FALSE(ToCloudView(c, &error).has_value());
  EXPECT_NE(error.find("duplicate field 'extra_17'"), std::string::npos) << error;
}

TEST(Convert, ImplausibleImuSamplesAreRejected) {
  ImuSample s;
  s.stamp_s = 100.25;
  s.angular_velocity = {0.1, -0.2, 0.3};
  s.linear_acceleration = {0.0, 0.5, 9.81};
  std::string error;
  auto msg = ToImuMsg(s, "imu");
  ASSERT_TRUE(ToImuSample(msg, &error).has_value()) << error;
  auto absurd = msg;
  absurd.linear_acceleration().z(1e6);
  EXPECT_FALSE(ToImuSample(absurd, &error).has_value());
  EXPECT_NE(error.find("beyond any IMU's range"), std::string::npos) << error;
  absurd = msg;
  absurd.angular_velocity().x(-41.0);
  EXPECT_FALSE(ToImuSample(absurd, &error).has_value());
  auto zeros = ToImuMsg(ImuSample{}, "imu");
  zeros.header().stamp(msg.header().stamp());
  EXPECT_FALSE(ToImuSample(zeros, &error).has_value());
  EXPECT_NE(error.find("all zeros"), std::string::npos) << error;
  auto unstamped = msg;
  unstamped.header().stamp(msgs::TimeFromNanoseconds(0));
  EXPECT_FALSE(ToImuSample(unstamped, &error).has_value());
  EXPECT_NE(error.find("stamp 0"), std::string::npos) << error;
  // At the limits, still accepted (a hard but real manoeuvre).
  auto hard = msg;
  hard.angular_velocity().z(kImuMaxAngularVelocity);
  hard.linear_acceleration().x(-kImuMaxAcceleration);
  EXPECT_TRUE(ToImuSample(hard, &error).has_value()) << error;
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

TEST(SkeletonPlanes, MarkerGeometryFromTheInlierScatter) {
  // A wall x = 5 (normal -x, facing the origin), inliers spread uniformly over 20 m along y and
  // 4 m along z with 2 cm thickness: sigma = L / sqrt(12).
  SkeletonPlane sp;
  sp.track_id = 42;
  sp.age = 7;
  sp.plane.n = Eigen::Vector3d(-1, 0, 0);
  sp.plane.d = 5.0;
  sp.centroid = Eigen::Vector3d(5, 1, 2);
  sp.num_inliers = 1000;
  const double sy = 20.0 / std::sqrt(12.0), sz = 4.0 / std::sqrt(12.0), sx = 0.02;
  sp.scatter = Eigen::Vector3d(sx * sx, sy * sy, sz * sz).asDiagonal();
  sp.scatter *= sp.num_inliers;
  sp.incremental = true;
  SkeletonPlane untracked = sp;
  untracked.track_id = -1;

  const auto msg = ToSkeletonPlaneArray({sp, untracked}, 12.5, "odom");
  EXPECT_EQ(msg.header().frame_id(), "odom");
  ASSERT_EQ(msg.planes().size(), 1u) << "planes without a track id are not published";
  const auto& m = msg.planes()[0];
  EXPECT_EQ(m.id(), 42u);
  EXPECT_EQ(m.age(), 7u);
  EXPECT_EQ(m.inlier_count(), 1000u);
  EXPECT_TRUE(m.incremental());
  EXPECT_DOUBLE_EQ(m.offset(), 5.0);
  EXPECT_NEAR(m.size().x(), 4.0 * sy, 1e-9);  // major axis: the 20 m direction
  EXPECT_NEAR(m.size().y(), 4.0 * sz, 1e-9);
  EXPECT_NEAR(m.size().z(), sx, 1e-9);  // RMS thickness
  const Eigen::Quaterniond q(m.orientation().w(), m.orientation().x(), m.orientation().y(),
                             m.orientation().z());
  const Eigen::Matrix3d R = q.toRotationMatrix();
  EXPECT_NEAR(std::abs(R.col(0).dot(Eigen::Vector3d::UnitY())), 1.0, 1e-9) << "x = major axis";
  EXPECT_NEAR(R.col(2).dot(Eigen::Vector3d(-1, 0, 0)), 1.0, 1e-9) << "z = normal";
  EXPECT_NEAR(R.determinant(), 1.0, 1e-9);
}

TEST(SkeletonPlanes, NoScatterStillGivesAValidOrientation) {
  SkeletonPlane sp;
  sp.track_id = 1;
  sp.plane.n = Eigen::Vector3d(0, 0, 1);
  const auto msg = ToSkeletonPlaneArray({sp}, 0.0, "odom");
  ASSERT_EQ(msg.planes().size(), 1u);
  const auto& o = msg.planes()[0].orientation();
  EXPECT_NEAR(o.x() * o.x() + o.y() * o.y() + o.z() * o.z() + o.w() * o.w(), 1.0, 1e-9);
  EXPECT_DOUBLE_EQ(msg.planes()[0].size().x(), 0.0);
  EXPECT_FALSE(msg.planes()[0].incremental());
}

}  // namespace
}  // namespace ppf::bridge
