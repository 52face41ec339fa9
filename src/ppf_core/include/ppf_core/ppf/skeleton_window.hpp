// The skeleton-plane window F in the world frame (paper Sec. IV-B), with track identities.
//
// After each scan's update, the scan's fitted planes are moved to the world with the estimated
// pose (f_W = (T_world_lidar^-1)^T f_L, Theorem 1) and associated with existing tracks, so the same
// physical plane keeps its track id over time (ids are published to users):
//   - a plane that came from an accepted incremental guess continues the guessed track;
//   - any other plane continues the unclaimed track with the closest normal (within
//     track_max_angle_deg) whose plane passes within track_max_offset of the new inlier centroid;
//   - otherwise it starts a new track.
// Tracks not re-fitted for more than window_max_missed_scans scans leave; at most window_size
// tracks stay (most recently fitted first, then more inliers). Normals keep the orientation a
// track was created with (facing the sensor), so signed offsets are comparable over time.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/ppf/plane.hpp"
#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf_config.hpp"
#include "ppf_core/result_types.hpp"

namespace ppf {

class SkeletonWindow {
 public:
  explicit SkeletonWindow(const PpfConfig& config);

  // Window planes in guess order (recently fitted, then larger first).
  const std::vector<SkeletonPlane>& planes() const { return planes_; }
  bool empty() const { return planes_.empty(); }

  // The window's planes as incremental guesses in the frame of a scan taken at (predicted) pose
  // T_world_lidar: f_L = (T_lidar_world^-1)^T f_W.
  std::vector<PlaneGuess> GuessesInFrame(const Eigen::Isometry3d& T_world_lidar) const;

  // World-frame planes for skeleton residuals (same order as planes()).
  std::vector<Plane> WorldPlanes() const;

  // Moves `fitted` (scan frame) to the world with the estimated T_world_lidar and updates tracks.
  // Returns the track id given to each fitted plane (same order as `fitted`).
  std::vector<int64_t> Update(const std::vector<FittedPlane>& fitted,
                              const Eigen::Isometry3d& T_world_lidar);

  void Clear();

 private:
  PpfConfig config_;
  std::vector<SkeletonPlane> planes_;
  int64_t next_track_id_ = 0;
};

}  // namespace ppf
