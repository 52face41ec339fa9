#include "ppf_core/skeleton_residual.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "ppf_core/skeleton_window.hpp"

namespace ppf {

void ComputeSkeletonMatches(const std::vector<Eigen::Vector3f>& points_lidar,
                            const std::vector<int>& skeleton_indices,
                            const Eigen::Isometry3d& T_world_lidar,
                            const std::vector<Plane>& window_world, double eps,
                            std::vector<SkeletonMatch>* matches) {
  matches->clear();
  if (window_world.empty() || skeleton_indices.empty() || !(eps > 0.0)) return;
  // Fold the pose into the planes once: |f_W . (T p)| = |((T^-1)^T... )| -> plane in LiDAR frame,
  // f_L = (T_lidar_world^-1)^T f_W, so each point costs one dot product per plane.
  const Eigen::Isometry3d T_lidar_world = T_world_lidar.inverse();
  const int np = static_cast<int>(window_world.size());
  std::vector<Plane> local(np);
  for (int j = 0; j < np; ++j) local[j] = TransformPlane(T_lidar_world, window_world[j]);

  const long n = static_cast<long>(skeleton_indices.size());
  const long num_points = static_cast<long>(points_lidar.size());
  std::vector<SkeletonMatch> per_point(n);
#pragma omp parallel for schedule(static) if (n > 32768)
  for (long i = 0; i < n; ++i) {
    SkeletonMatch m;
    const int idx = skeleton_indices[i];
    if (idx >= 0 && idx < num_points) {
      const Eigen::Vector3d p = points_lidar[idx].cast<double>();
      double best = std::numeric_limits<double>::infinity();
      for (int j = 0; j < np; ++j) {
        const double s = local[j].SignedDistance(p);
        if (std::abs(s) < std::abs(best)) {
          best = s;
          m.plane_index = j;
        }
      }
      if (std::abs(best) < eps) {
        m.point_index = idx;
        m.signed_distance = best;  // rigid transforms preserve the (unit-normal) distance
      }
    }
    per_point[i] = m;
  }
  for (const SkeletonMatch& m : per_point) {
    if (m.point_index >= 0) matches->push_back(m);
  }
}

SkeletonResidualProvider::SkeletonResidualProvider(const SkeletonWindow* window, double eps)
    : window_(window), eps_(eps) {}

void SkeletonResidualProvider::Reset() {
  frame_ = nullptr;
  planes_world_.clear();
  skeleton_indices_.clear();
  matches_.clear();
}

void SkeletonResidualProvider::BeginScan(const ScanFrame& frame) {
  frame_ = &frame;
  planes_world_ = window_ ? window_->WorldPlanes() : std::vector<Plane>{};
  skeleton_indices_.clear();
  const size_t n = std::min(frame.labels.size(), frame.points_lidar.size());
  for (size_t i = 0; i < n; ++i) {
    if (frame.labels[i] == PointLabel::kSkeleton) skeleton_indices_.push_back(static_cast<int>(i));
  }
  matches_.clear();
}

void SkeletonResidualProvider::ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                                           std::vector<PointPlaneRow>* rows) {
  if (frame_ == nullptr) return;
  ComputeSkeletonMatches(frame_->points_lidar, skeleton_indices_, T_world_lidar, planes_world_,
                         eps_, &matches_);
  rows->reserve(rows->size() + matches_.size());
  for (const SkeletonMatch& m : matches_) {
    PointPlaneRow row;
    row.point_lidar = frame_->points_lidar[m.point_index].cast<double>();
    row.normal_world = planes_world_[m.plane_index].n;
    row.offset = planes_world_[m.plane_index].d;
    rows->push_back(row);
  }
}

}  // namespace ppf
