// The registration's residual sources (see lio_ppf.hpp for the pipeline around them).
//
//   AddScan -> decode -> IMU propagate -> de-skew -> downsample
//           -> SkeletonTracker::Split      (kPpf: labels skeleton / scattered / discarded)
//           -> IEKF: every iteration, every ResidualProvider::ComputeRows(current T_world_lidar)
//           -> SkeletonTracker::Finish, ResidualProvider::EndScan   (with the converged pose)
//           -> insert points labelled kScattered into the kNN voxel map
//
// kKnn mode: no split, every point is kScattered, the kNN provider (knn_residual.hpp) makes all
// rows. kPpf mode: the skeleton tracker's provider (skeleton_residual.hpp) makes the skeleton
// points' rows; the kNN provider still serves the kScattered points, and only those enter the map.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/result_types.hpp"

namespace ppf {

class VoxelMap;
class PlanePatchMap;

// One point-to-plane residual row: r = n_world . (T_world_lidar * point_lidar) + offset.
struct PointPlaneRow {
  Eigen::Vector3d point_lidar = Eigen::Vector3d::Zero();  // de-skewed, LiDAR frame at scan end
  Eigen::Vector3d normal_world = Eigen::Vector3d::UnitZ();  // unit length
  double offset = 0.0;                                      // plane: n . x + offset = 0
  double weight = 1.0;  // scales the information of the row (1 = laser_point_std noise)
};

// The downsampled, de-skewed scan as the registration sees it.
struct ScanFrame {
  double stamp_s = 0.0;                     // scan end = time of the filter state
  std::vector<Eigen::Vector3f> points_lidar;  // de-skewed to scan end, downsampled, LiDAR frame
  std::vector<PointLabel> labels;           // same size as points_lidar; default kScattered
  Eigen::Isometry3d T_world_lidar_predicted = Eigen::Isometry3d::Identity();  // IMU prediction
  Eigen::Isometry3d T_imu_lidar = Eigen::Isometry3d::Identity();
  const VoxelMap* map = nullptr;            // the kNN map before this scan's insertion
  // kPpf: the skeleton's surfaces (the kNN map holds the scattered points only). Set only for the
  // scan-alone probes (hypothesis_search.hpp), where a point the kNN map does not cover meets
  // the nearest patch of its cell; the IEKF's providers do not read it.
  const PlanePatchMap* patches = nullptr;
  // Points farther than this from the LiDAR give no residual (0 = all do); they still enter the
  // map, to give residuals once the sensor is nearer (IekfOptions::residual_max_range).
  double residual_max_range = 0.0;
  bool GivesResidual(const Eigen::Vector3f& p_lidar) const {
    return !(residual_max_range > 0.0) ||
           p_lidar.squaredNorm() <= residual_max_range * residual_max_range;
  }
};

// Produces point-to-plane rows for the IEKF. ComputeRows is called once per iteration with the
// current estimate, so matches are re-established every iteration; it may use OpenMP internally.
class ResidualProvider {
 public:
  virtual ~ResidualProvider() = default;
  virtual std::string Name() const = 0;
  // Called once per scan before the first iteration; `frame` outlives the scan's update.
  virtual void BeginScan(const ScanFrame& frame) = 0;
  // Append this provider's rows for the pose estimate T_world_lidar.
  virtual void ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                           std::vector<PointPlaneRow>* rows) = 0;

  // ComputeRows in three steps, so that the IEKF runs the per-point loops of all its providers
  // in one OpenMP team per iteration: a passive worker sleeps between regions, and each team
  // start waits for its wake-up (docs/decisions.md, "Parallel skeleton matching"). PrepareRows,
  // on the calling thread, sizes everything the loop writes and says what it has for a team;
  // RowsInTeam is called by every thread of that team (or by the calling thread alone) and shares
  // the points out with an orphaned `omp for nowait`, each point writing only its own slot;
  // FinishRows, on the calling thread after the team has ended, appends the rows in point order.
  // The rows are those of ComputeRows, bit for bit. The defaults leave it all to ComputeRows in
  // FinishRows.
  struct TeamWork {
    size_t points = 0;      // iterations RowsInTeam shares out (0: it has nothing to do)
    size_t team_above = 0;  // a team pays for itself above this many points
    int threads = 1;        // the provider's configured thread count, resolved
  };
  virtual TeamWork PrepareRows(const Eigen::Isometry3d& /*T_world_lidar*/) { return {}; }
  virtual void RowsInTeam() {}
  virtual void FinishRows(const Eigen::Isometry3d& T_world_lidar,
                          std::vector<PointPlaneRow>* rows) {
    ComputeRows(T_world_lidar, rows);
  }
  virtual void EndScan(const Eigen::Isometry3d& /*T_world_lidar*/) {}
  virtual void Reset() {}
};

}  // namespace ppf
