// Core skeleton-plane window (skeleton_window.hpp, world frame) -> ppf_msgs/SkeletonPlaneArray.
// See src/ppf_msgs_idl/msg/SkeletonPlane.msg for the field meanings.
#pragma once

#include <string>
#include <vector>

#include "ppf_core/skeleton_window.hpp"
#include "ppf_msgs/msg/SkeletonPlaneArray.h"

namespace ppf::bridge {

// `planes` are world-frame planes (the node's odom frame); `incremental_track_ids` lists the
// tracks whose latest fit came from an incremental guess. Fields the window does not track are
// filled conservatively: orientation is built from the normal alone (z = normal, x = a
// perpendicular axis), size is zero. Planes with a negative track id (never tracked) are skipped.
ppf_msgs::msg::SkeletonPlaneArray ToSkeletonPlaneArray(
    const std::vector<SkeletonPlane>& planes, double stamp_s, const std::string& frame_id,
    const std::vector<int64_t>& incremental_track_ids = {});

}  // namespace ppf::bridge
