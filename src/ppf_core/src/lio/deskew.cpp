#include "ppf_core/lio/deskew.hpp"

#include <algorithm>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ppf_core/lio/so3.hpp"

namespace ppf {

namespace {

// One IMU segment of the trace seen from the LiDAR at the scan end. With T_lidarend_world = [A|b]
// and tau = t - knot.t, a point q (IMU frame) at time t in the segment lands at
//   A (R_k Exp(w tau) q + p_k + v_k tau + acc tau^2 / 2) + b = M Exp(w tau) q + c + d tau + e
//   tau^2:
// everything but the small rotation is the segment's, computed once instead of per point.
struct SegmentFromEnd {
  double t = 0.0;
  Eigen::Matrix3d M;
  Eigen::Vector3d c, d, e, w;
};

}  // namespace

void DeskewToEnd(const std::vector<TimedPoint>& points, const PoseTrace& trace, double t_end,
                 const Eigen::Isometry3d& T_imu_lidar, std::vector<Eigen::Vector3f>* out,
                 int num_threads) {
  out->resize(points.size());
  const Eigen::Isometry3d T_lidarend_world = (trace.PoseAt(t_end) * T_imu_lidar).inverse();
  const Eigen::Matrix3d A = T_lidarend_world.linear();
  const Eigen::Vector3d b = T_lidarend_world.translation();
  const long n = static_cast<long>(points.size());
  if (trace.knots.empty()) {
    // PoseAt's identity: every time has the same pose.
    const Eigen::Isometry3d T = T_lidarend_world * T_imu_lidar;
    for (long i = 0; i < n; ++i) {
      (*out)[static_cast<size_t>(i)] =
          (T * points[static_cast<size_t>(i)].p.cast<double>()).cast<float>();
    }
    return;
  }
  std::vector<SegmentFromEnd> segments(trace.knots.size());
  for (size_t k = 0; k < trace.knots.size(); ++k) {
    const ImuKnot& knot = trace.knots[k];
    SegmentFromEnd& s = segments[k];
    s.t = knot.t;
    s.M = A * knot.R;
    s.c = A * knot.p + b;
    s.d = A * knot.v;
    s.e = 0.5 * (A * knot.acc_world);
    s.w = knot.omega;
  }
#ifdef _OPENMP
  const int threads = num_threads > 0 ? num_threads : omp_get_max_threads();
#endif
#pragma omp parallel for schedule(static) num_threads(threads)
  for (long i = 0; i < n; ++i) {
    const TimedPoint& tp = points[static_cast<size_t>(i)];
    // The segment PoseAt uses: the last whose start is <= t, the first before them all.
    auto it = std::upper_bound(segments.begin(), segments.end(), tp.t,
                               [](double v, const SegmentFromEnd& s) { return v < s.t; });
    const SegmentFromEnd& s = (it == segments.begin()) ? segments.front() : *(it - 1);
    const double tau = tp.t - s.t;
    const Eigen::Vector3d q = T_imu_lidar * tp.p.cast<double>();
    const Eigen::Vector3d p_end = s.M * SO3ExpApply(s.w * tau, q) + s.c + (s.d + s.e * tau) * tau;
    (*out)[static_cast<size_t>(i)] = p_end.cast<float>();
  }
}

}  // namespace ppf
