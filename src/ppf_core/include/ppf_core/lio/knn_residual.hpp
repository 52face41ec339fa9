// kNN point-to-plane residuals against the voxel map (the Faster-LIO style registration).
// For every kScattered point: k nearest map points; least-squares plane through them (PCA);
// accepted only if all k lie within plane_threshold of the plane (a flat patch); then the row
// r = n . (T_world_lidar p) + d, gated by |r| < max_residual. OpenMP-parallel over points.
#pragma once

#include <atomic>
#include <string>
#include <vector>

#include "ppf_core/config.hpp"  // this stage's options
#include "ppf_core/lio/residual_provider.hpp"
#include "ppf_core/lio/voxel_map.hpp"
#include "ppf_core/ppf/plane.hpp"

namespace ppf {

// Least-squares plane n.x + d = 0 through `pts` (>= 3). Returns false if the points do not span a
// plane (std across their main direction below min_spread) or if a point is farther than
// `threshold` from the plane.
bool FitPlane(const std::vector<Eigen::Vector3f>& pts, double threshold, Eigen::Vector3d* n,
              double* d, double min_spread = 0.0);

// A point of the scan with what the last kNN search found for it (Associations).
struct AssociatedPoint {
  Eigen::Vector3f point_lidar = Eigen::Vector3f::Zero();
  bool covered = false;    // k neighbours within reach
  bool has_plane = false;  // ... and they fitted a plane (normal, d: n . x + d = 0, world)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;
};

class KnnResidualProvider : public ResidualProvider {
 public:
  explicit KnnResidualProvider(const KnnOptions& options = KnnOptions()) : options_(options) {}
  std::string Name() const override { return "knn"; }
  void BeginScan(const ScanFrame& frame) override;
  void ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                   std::vector<PointPlaneRow>* rows) override;
  TeamWork PrepareRows(const Eigen::Isometry3d& T_world_lidar) override;
  void RowsInTeam() override;
  void FinishRows(const Eigen::Isometry3d& T_world_lidar,
                  std::vector<PointPlaneRow>* rows) override;
  // What the last ComputeRows of this scan found for each of its points (the scattered points
  // within reach): false if nothing was searched since BeginScan, or k is too large to keep.
  bool Associations(std::vector<AssociatedPoint>* out) const;
  // Whether KnnOptions::search_again_distance applies to the scans from now on. Its premise is a
  // prediction near the pose, so that later iterations move a point by millimetres; a scan
  // registered from LiDAR-only guesses (no IMU, or re-localizing after a loss) moves by more, and
  // a neighbour set kept from its first iterations would hold it where they were made.
  void SetKeepNeighbours(bool keep) { keep_neighbours_ = keep; }
  // Searches the neighbours of frame's points at T_world_lidar (those that give a residual, in
  // PrefetchOrder) on the calling thread until `stop` is set, for the next BeginScan of the same
  // frame. It runs beside the pre-fit, which decides which points are scattered: the scan's
  // first iteration then skips the search of each scattered point whose query lands on the
  // world point searched here (the same query on the same map: the same neighbours and plane).
  // The searches of points the split labels otherwise are spent for nothing; the map must not
  // change until that BeginScan. likely_planes: scan frame, the planes the pre-fit will most
  // likely take.
  void Prefetch(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                const std::vector<Plane>& likely_planes, double band,
                const std::atomic<bool>& stop);
  // The order Prefetch searches in: the points that give a residual, those within `band` of
  // none of likely_planes first, each part in index order (valid until the next call).
  const std::vector<size_t>& PrefetchOrder(const ScanFrame& frame,
                                           const std::vector<Plane>& likely_planes, double band);
  // Points Prefetch searched for the last BeginScan, and how many of them were scattered.
  size_t prefetched() const { return prefetched_; }
  size_t prefetched_scattered() const { return prefetched_scattered_; }

 private:
  KnnOptions options_;
  bool keep_neighbours_ = true;
  const ScanFrame* frame_ = nullptr;
  std::vector<size_t> indices_;  // kScattered points of the frame
  // Per-call buffers kept between the iterations and scans: one slot per indexed point.
  std::vector<PointPlaneRow> tmp_;
  std::vector<char> ok_;
  // The pose of the rows being computed, between PrepareRows and FinishRows.
  bool team_ready_ = false;
  Eigen::Isometry3d team_T_ = Eigen::Isometry3d::Identity();
  // The last plane fitted for each indexed point and the neighbours it was fitted to. Between the
  // filter's iterations the pose moves little and most points find the same k neighbours: the
  // same input gives the same plane, so the fit is reused instead of solved again.
  static constexpr size_t kMaxCachedK = 8;
  struct CachedFit {
    Eigen::Vector3f nn[kMaxCachedK];
    size_t count = 0;  // 0: nothing cached
    // Where the last search of this scan was made and whether it found k neighbours; with
    // search_again_distance its result stands while the point stays near there.
    Eigen::Vector3f searched_at = Eigen::Vector3f::Zero();
    bool searched = false;
    bool found = false;
    bool ok = false;
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    double d = 0.0;
  };
  std::vector<CachedFit> fits_;
  // Prefetch's searches, one slot per point of prefetch_frame_ (searched == false: not reached).
  const ScanFrame* prefetch_frame_ = nullptr;
  std::vector<CachedFit> prefetch_;
  std::vector<size_t> order_, later_;  // Prefetch's search order (scratch)
  size_t prefetched_ = 0;
  size_t prefetched_scattered_ = 0;

  // The k-neighbour search of the world point q_w and its plane fit, into *fit (as the first
  // iteration of a scan makes them).
  void SearchAndFit(const VoxelMap& map, const Eigen::Vector3f& q_w, size_t k,
                    std::vector<Eigen::Vector3f>* nn, CachedFit* fit) const;
};

}  // namespace ppf
