// Core skeleton-plane window (skeleton_window.hpp, world frame) -> ppf_msgs/SkeletonPlaneArray.
// See src/ppf_msgs_idl/msg/SkeletonPlane.msg for the field meanings.
#pragma once

#include <string>
#include <vector>

#include "ppf_core/ppf/skeleton_window.hpp"
#include "ppf_msgs/msg/SkeletonPlaneArray.h"

namespace ppf::bridge {

// `planes` are world-frame planes (the node's odom frame). orientation/size come from the latest
// fit's inlier scatter: z = normal, x = major in-plane axis; size x, y = 4 sigma (a +-2 sigma box)
// along the major/minor axes, z = RMS distance of the inliers from the plane. Planes with a
// negative track id (never tracked) are skipped.
ppf_msgs::msg::SkeletonPlaneArray ToSkeletonPlaneArray(const std::vector<SkeletonPlane>& planes,
                                                       double stamp_s,
                                                       const std::string& frame_id);

}  // namespace ppf::bridge
