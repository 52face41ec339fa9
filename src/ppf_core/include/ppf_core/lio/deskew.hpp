// Motion compensation: every point is moved from the LiDAR pose at its own time to the LiDAR pose
// at the scan END (the time of the filter state after propagation), using the IMU poses of the
// PoseTrace (interpolated inside each IMU segment with its constant rate and acceleration).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/time_field.hpp"

namespace ppf {

// Out: points in the LiDAR frame at trace time t_end. Points keep their order.
// num_threads: OpenMP threads (0 = OpenMP default).
void DeskewToEnd(const std::vector<TimedPoint>& points, const PoseTrace& trace, double t_end,
                 const Eigen::Isometry3d& T_imu_lidar, std::vector<Eigen::Vector3f>* out,
                 int num_threads = 0);

}  // namespace ppf
