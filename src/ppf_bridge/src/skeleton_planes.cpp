#include "ppf_bridge/skeleton_planes.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "ppf_bridge/convert.hpp"
#include "ppf_msgs_cdr/time.hpp"

namespace ppf::bridge {

ppf_msgs::msg::SkeletonPlaneArray ToSkeletonPlaneArray(const std::vector<SkeletonPlane>& planes,
                                                       double stamp_s,
                                                       const std::string& frame_id) {
  ppf_msgs::msg::SkeletonPlaneArray out;
  out.header().stamp(msgs::TimeFromSeconds(stamp_s));
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
    // In-plane principal axes of the inliers: the scatter projected onto the plane.
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - n * n.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(P * p.scatter * P);
    Eigen::Vector3d x = es.eigenvectors().col(2);  // largest eigenvalue
    x = (x - x.dot(n) * n);
    if (!(x.norm() > 1e-6) || !p.scatter.allFinite()) {
      // No spread (or none recorded): any axis perpendicular to the normal.
      const Eigen::Vector3d helper =
          std::abs(n.x()) > 0.9 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
      x = helper - helper.dot(n) * n;
    }
    x.normalize();
    Eigen::Matrix3d R;
    R.col(0) = x;
    R.col(1) = n.cross(x);
    R.col(2) = n;
    const Eigen::Quaterniond q(R);
    m.orientation().x(q.x());
    m.orientation().y(q.y());
    m.orientation().z(q.z());
    m.orientation().w(q.w());
    const double count = std::max(1, p.num_inliers);
    auto sigma = [&](const Eigen::Vector3d& axis) {
      return std::sqrt(std::max(0.0, axis.dot(p.scatter * axis)) / count);
    };
    m.size().x(4.0 * sigma(R.col(0)));
    m.size().y(4.0 * sigma(R.col(1)));
    m.size().z(sigma(n));
    m.inlier_count(static_cast<uint32_t>(p.num_inliers < 0 ? 0 : p.num_inliers));
    m.incremental(p.incremental);
    out.planes().push_back(m);
  }
  return out;
}

}  // namespace ppf::bridge
