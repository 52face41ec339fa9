#include "ppf_bridge/skeleton_planes.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "ppf_bridge/convert.hpp"

namespace ppf::bridge {

ppf_msgs::msg::SkeletonPlaneArray ToSkeletonPlaneArray(
    const std::vector<SkeletonPlane>& planes, double stamp_s, const std::string& frame_id,
    const std::vector<int64_t>& incremental_track_ids) {
  ppf_msgs::msg::SkeletonPlaneArray out;
  out.header().stamp(TimeFromSeconds(stamp_s));
  out.header().frame_id(frame_id);
  for (const SkeletonPlane& p : planes) {
    if (p.track_id < 0) continue;
    ppf_msgs::msg::SkeletonPlane m;
    m.id(static_cast<uint32_t>(p.track_id));
    m.age(static_cast<uint32_t>(p.age < 0 ? 0 : p.age));
    const Eigen::Vector3d n = p.plane.n.normalized();
    m.normal().x(n.x());
    m.normal().y(n.y());
    m.normal().z(n.z());
    m.offset(p.plane.d);
    m.centroid().x(p.centroid.x());
    m.centroid().y(p.centroid.y());
    m.centroid().z(p.centroid.z());
    // z axis = normal; x axis = the world axis least aligned with it, made perpendicular.
    Eigen::Vector3d helper = Eigen::Vector3d::UnitX();
    if (std::abs(n.x()) > 0.9) helper = Eigen::Vector3d::UnitY();
    const Eigen::Vector3d x = (helper - helper.dot(n) * n).normalized();
    Eigen::Matrix3d R;
    R.col(0) = x;
    R.col(1) = n.cross(x);
    R.col(2) = n;
    const Eigen::Quaterniond q(R);
    m.orientation().x(q.x());
    m.orientation().y(q.y());
    m.orientation().z(q.z());
    m.orientation().w(q.w());
    m.inlier_count(static_cast<uint32_t>(p.num_inliers < 0 ? 0 : p.num_inliers));
    m.incremental(std::find(incremental_track_ids.begin(), incremental_track_ids.end(),
                            p.track_id) != incremental_track_ids.end());
    out.planes().push_back(m);
  }
  return out;
}

}  // namespace ppf::bridge
