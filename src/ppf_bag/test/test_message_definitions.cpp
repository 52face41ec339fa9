#include <gtest/gtest.h>

#include "ppf_bag/bag.hpp"

using ppf::bag::MessageDefinition;

namespace {

const std::string kSep = std::string(80, '=') + "\n";

TEST(MessageDefinition, ImuHasAllDependenciesOnce) {
  const std::string d = MessageDefinition("sensor_msgs/msg/Imu");
  ASSERT_FALSE(d.empty());
  // The root type's own fields come before the first dependency.
  EXPECT_LT(d.find("std_msgs/Header header"), d.find(kSep));
  EXPECT_LT(d.find("float64[9] linear_acceleration_covariance"), d.find(kSep));
  for (const char* dep : {"std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Quaternion",
                          "geometry_msgs/Vector3"}) {
    const std::string marker = kSep + "MSG: " + dep + "\n";
    const size_t at = d.find(marker);
    EXPECT_NE(at, std::string::npos) << dep;
    EXPECT_EQ(d.find(marker, at + 1), std::string::npos) << dep << " appears twice";
  }
  EXPECT_NE(d.find("float64 w 1"), std::string::npos);
}

TEST(MessageDefinition, AllRequiredTypesResolve) {
  for (const char* t : {"sensor_msgs/msg/PointCloud2", "sensor_msgs/msg/Imu", "nav_msgs/msg/Odometry",
                        "nav_msgs/msg/Path", "tf2_msgs/msg/TFMessage", "geometry_msgs/msg/PoseStamped",
                        "ppf_msgs/msg/SkeletonPlaneArray"}) {
    EXPECT_FALSE(MessageDefinition(t).empty()) << t;
  }
  const std::string pc2 = MessageDefinition("sensor_msgs/msg/PointCloud2");
  EXPECT_NE(pc2.find("MSG: sensor_msgs/PointField\n"), std::string::npos);
  EXPECT_NE(pc2.find("uint8[] data"), std::string::npos);
  const std::string odom = MessageDefinition("nav_msgs/msg/Odometry");
  for (const char* dep : {"geometry_msgs/PoseWithCovariance", "geometry_msgs/TwistWithCovariance",
                          "geometry_msgs/Pose", "geometry_msgs/Twist", "geometry_msgs/Point"}) {
    EXPECT_NE(odom.find(std::string("MSG: ") + dep + "\n"), std::string::npos) << dep;
  }
  EXPECT_NE(MessageDefinition("tf2_msgs/msg/TFMessage").find("MSG: geometry_msgs/Transform\n"),
            std::string::npos);
  const std::string planes = MessageDefinition("ppf_msgs/msg/SkeletonPlaneArray");
  EXPECT_NE(planes.find("SkeletonPlane[] planes"), std::string::npos);
  EXPECT_NE(planes.find("MSG: ppf_msgs/SkeletonPlane\n"), std::string::npos);
  EXPECT_NE(planes.find("uint32 inlier_count"), std::string::npos);
  EXPECT_NE(planes.find("MSG: geometry_msgs/Point\n"), std::string::npos);
}

TEST(MessageDefinition, UnknownTypesAreEmpty) {
  EXPECT_EQ(MessageDefinition("my_pkg/msg/Nothing"), "");
  EXPECT_EQ(MessageDefinition(""), "");
  EXPECT_EQ(MessageDefinition("Imu"), "");
  EXPECT_EQ(MessageDefinition("sensor_msgs/srv/Imu"), "");
}

}  // namespace
