// ROS 2 message <-> core conversions. The core never sees a generated type; the DDS node, the
// offline runner and the simulator all go through these functions, so a convention (time base,
// covariance layout, frame names) is decided in exactly one place.
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

double ToSeconds(const builtin_interfaces::msg::Time& t);
int64_t ToNanoseconds(const builtin_interfaces::msg::Time& t);
builtin_interfaces::msg::Time TimeFromNanoseconds(int64_t ns);
builtin_interfaces::msg::Time TimeFromSeconds(double s);

// A view into `msg` (no copy of the point data): `msg` must outlive the view. Structural checks
// (point_step vs fields, data size vs width*height*point_step) are the core's job, so that the
// same rules hold for every input path; this only fails for layouts that cannot be described at
// all (an unknown PointField datatype), with the reason in `error`.
std::optional<CloudView> ToCloudView(const sensor_msgs::msg::PointCloud2& msg,
                                     std::string* error = nullptr);

// Rejects samples with non-finite values (a driver glitch must not poison the filter).
std::optional<ImuSample> ToImuSample(const sensor_msgs::msg::Imu& msg, std::string* error = nullptr);

sensor_msgs::msg::Imu ToImuMsg(const ImuSample& sample, const std::string& frame_id);

}  // namespace ppf::bridge
