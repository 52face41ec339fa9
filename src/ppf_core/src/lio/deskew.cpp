#include "ppf_core/lio/deskew.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace ppf {

void DeskewToEnd(const std::vector<TimedPoint>& points, const PoseTrace& trace, double t_end,
                 const Eigen::Isometry3d& T_imu_lidar, std::vector<Eigen::Vector3f>* out,
                 int num_threads) {
  out->resize(points.size());
  const Eigen::Isometry3d T_lidarend_world =
      (trace.PoseAt(t_end) * T_imu_lidar).inverse();
  const long n = static_cast<long>(points.size());
#ifdef _OPENMP
  const int threads = num_threads > 0 ? num_threads : omp_get_max_threads();
#endif
#pragma omp parallel for schedule(static) num_threads(threads)
  for (long i = 0; i < n; ++i) {
    const TimedPoint& tp = points[static_cast<size_t>(i)];
    // p_lidar_end = T_lidarend_world * T_world_imu(t) * T_imu_lidar * p_lidar(t)
    const Eigen::Isometry3d T_world_imu_t = trace.PoseAt(tp.t);
    const Eigen::Vector3d p_w = T_world_imu_t * (T_imu_lidar * tp.p.cast<double>());
    (*out)[static_cast<size_t>(i)] = (T_lidarend_world * p_w).cast<float>();
  }
}

}  // namespace ppf
