// ROS 2 message <-> core conversions. The core never sees a generated type; the DDS node, the
// offline runner and the simulator all go through these functions, so a convention (time base,
// covariance layout, frame names) is decided in exactly one place. Stamps convert through
// ppf_msgs_cdr/time.hpp.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "builtin_interfaces/msg/Time.h"
#include "ppf_core/cloud_view.hpp"
#include "ppf_core/imu_sample.hpp"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/PointCloud2.h"

namespace ppf::bridge {

inline constexpr uint32_t kNanosecPerSecond = 1000000000u;

// "" for a valid builtin_interfaces/Time, else the reason: nanosec must be below one second
// (sec may be anything; stamps <= 0 are each caller's policy).
std::string CheckStamp(const builtin_interfaces::msg::Time& stamp);

// A view into `msg` (no copy of the point data): `msg` must outlive the view. Fails, with the
// reason in `error`, for a header stamp CheckStamp refuses and for a layout that cannot be read
// as declared: no fields at all (for a cloud with points), an unknown PointField datatype, a
// duplicate field name, a field beyond point_step, data longer or shorter than height * row_step,
// and everything the core's ValidateCloudLayout refuses (missing or non-float x/y/z, big-endian,
// a non-zero row_step < width * point_step). row_step 0 is read as width * point_step: drivers
// have published it for unorganized clouds (the data must then be exactly height * width *
// point_step bytes), and the core reads it the same way; the node says so once per run. The
// offline runner and the DDS node both go through here, so one rule set holds for every input
// path. An empty cloud is a valid view.
std::optional<CloudView> ToCloudView(const sensor_msgs::msg::PointCloud2& msg,
                                     std::string* error = nullptr);

// Largest |angular velocity| (rad/s) and |acceleration| (m/s^2) component accepted: above the
// full scale of robot IMUs (+-2000 deg/s = 34.9 rad/s; +-16 g, some parts 20 g).
inline constexpr double kImuMaxAngularVelocity = 40.0;
inline constexpr double kImuMaxAcceleration = 200.0;

// Rejects samples a driver glitch produces, so they never reach the filter: a stamp CheckStamp
// refuses, non-finite values, all six values exactly zero (an uninitialized message), stamp <= 0,
// and values beyond the limits above. The reason goes to `error`.
std::optional<ImuSample> ToImuSample(const sensor_msgs::msg::Imu& msg,
                                     std::string* error = nullptr);

sensor_msgs::msg::Imu ToImuMsg(const ImuSample& sample, const std::string& frame_id);

}  // namespace ppf::bridge
