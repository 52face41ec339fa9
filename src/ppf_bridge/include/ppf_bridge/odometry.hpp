// Core ScanResult -> ROS 2 outputs of the odometry node: nav_msgs/Odometry, the odom -> base
// transform for /tf, and PoseStamped for nav_msgs/Path. One place decides the conventions:
//   - the pose is the IMU body pose T_world_imu: the base frame IS the IMU frame (publish a
//     static base_link -> sensor transform elsewhere if the robot's base differs);
//   - header.stamp = ScanResult::stamp_s (scan end, the time the pose refers to);
//   - pose covariance in ROS order [x y z rx ry rz] (the core's is [rot, pos]);
//   - twist in the child (base) frame, as nav_msgs/Odometry specifies.
#pragma once

#include <string>

#include <Eigen/Core>

#include "geometry_msgs/msg/PoseStamped.h"
#include "nav_msgs/msg/Odometry.h"
#include "ppf_core/lio_ppf.hpp"
#include "tf2_msgs/msg/TFMessage.h"

namespace ppf::bridge {

struct OdometryFrames {
  std::string odom_frame = "odom";
  std::string base_frame = "base_link";
};

// The twist's angular part is ScanResult::angular_velocity (bias-corrected gyro at the scan end,
// IMU frame); `angular_velocity_variance` fills the twist covariance's rotational diagonal (the
// filter does not estimate the rate, it integrates it).
nav_msgs::msg::Odometry ToOdometryMsg(const ScanResult& result, const OdometryFrames& frames,
                                      double angular_velocity_variance = 1e-4);

// tf2_msgs/TFMessage with the single transform odom -> base (parent odom, child base).
tf2_msgs::msg::TFMessage ToTfMessage(const ScanResult& result, const OdometryFrames& frames);

geometry_msgs::msg::PoseStamped ToPoseStamped(const ScanResult& result,
                                              const std::string& frame_id);

}  // namespace ppf::bridge
