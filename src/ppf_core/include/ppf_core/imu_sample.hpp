// One IMU measurement as the core consumes it, already in SI units of the driver's frame.
#pragma once

#include <Eigen/Core>

namespace ppf {

struct ImuSample {
  double stamp_s = 0.0;                                       // measurement time, seconds
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // rad/s, IMU frame
  // m/s^2 by default; the initializer detects drivers that report in g (norm ~1 at rest).
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();
};

}  // namespace ppf
