// Skeleton residuals (paper Eq. 10): each skeleton point (Omega) is matched to the nearest plane
// of the world-frame window F, and only if that distance is below the gate eps. There is no kNN
// search: the search space is <= window_size planes instead of the local point map.
//
// With a PlanePatchMap (plane_patch_map.hpp, SetPatchMap) a skeleton point whose world cell holds
// a patch of its own surface is matched to that patch instead (map-anchored; that header says
// why); the window planes remain the fallback.
//
// Matches are recomputed from scratch at every call (every IEKF iteration): no per-point
// "selected" flag survives between iterations, unlike the reference code where a stale flag kept
// matches from an earlier linearisation point.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "ppf_core/ppf/plane.hpp"
#include "ppf_core/ppf/plane_patch_map.hpp"
#include "ppf_core/lio/residual_provider.hpp"

namespace ppf {

class SkeletonWindow;
struct AssociatedPoint;  // knn_residual.hpp
struct PrefitResult;

// A skeleton point's last patch lookup within a scan (SkeletonResidualProvider::SetKeepDistance).
struct PatchLookup {
  bool done = false;
  Eigen::Vector3f at = Eigen::Vector3f::Zero();  // world position the lookup was made at
  const PlanePatchMap::Patch* patch = nullptr;   // its result (nullptr: no patch of its surface)
};

struct SkeletonMatch {
  int point_index = -1;          // index into the scan's points
  int plane_index = -1;          // index into the window planes passed in; -1 = a map patch
  double signed_distance = 0.0;  // n . (T_world_lidar p) + d, |.| < eps
  Plane plane;                   // the matched plane, world frame
};

// Eq. 10 for the points `skeleton_indices` of `points_lidar` at pose T_world_lidar. Appends one
// match per gated point to *matches (cleared first), in ascending point order.
void ComputeSkeletonMatches(const std::vector<Eigen::Vector3f>& points_lidar,
                            const std::vector<int>& skeleton_indices,
                            const Eigen::Isometry3d& T_world_lidar,
                            const std::vector<Plane>& window_world, double eps,
                            std::vector<SkeletonMatch>* matches);

// The same with a normal-consistency gate: `own_normals_lidar[i]` is the normal of the plane the
// pre-fitter assigned skeleton_indices[i] to (scan frame); a window plane is a candidate only if
// the angle between the normals is below normal_gate_deg (<= 0: no gate). Why: a point of a
// plane that is new in this scan (not in the window yet) lying within eps of another window plane
// (a wall's foot near the floor) would otherwise be matched to that plane.
void ComputeSkeletonMatches(const std::vector<Eigen::Vector3f>& points_lidar,
                            const std::vector<int>& skeleton_indices,
                            const std::vector<Eigen::Vector3d>& own_normals_lidar,
                            double normal_gate_deg, const Eigen::Isometry3d& T_world_lidar,
                            const std::vector<Plane>& window_world, double eps,
                            std::vector<SkeletonMatch>* matches);

struct SkeletonMatchLoop;  // skeleton_residual.cpp

// Residual rows of the skeleton points of a ScanFrame (labels == kSkeleton) against a window.
// The window is read at BeginScan (F from the previous scan, as in the reference pipeline; this
// scan's planes enter the window only after the update, see SkeletonTracker::Finish).
class SkeletonResidualProvider : public ResidualProvider {
 public:
  SkeletonResidualProvider(const SkeletonWindow* window, double eps);

  // Enables the normal-consistency gate (see above) using the pre-fit of the current scan, which
  // must be complete before BeginScan (SkeletonTracker does this). normal_gate_deg <= 0: off.
  void SetPrefitSource(const PrefitResult* prefit, double normal_gate_deg);
  // Map-anchored matches (needs the pre-fit source for each point's own normal); nullptr = off.
  // window_fallback: points whose cell has no patch of their surface yet are matched to the
  // window (true) or give no residual (false).
  void SetPatchMap(const PlanePatchMap* patches, bool window_fallback) {
    patches_ = patches;
    window_fallback_ = window_fallback;
  }
  // OpenMP threads for the matching loop (PpfConfig::num_threads); 0 = the OpenMP default.
  void SetNumThreads(int num_threads) { num_threads_ = num_threads; }
  // Metres; > 0: within one scan a point keeps the patch of its last lookup while its world
  // position stays within this distance of where the lookup was made (the residual is always
  // evaluated at the current pose); 0: every iteration looks up again. The caller sets it per
  // scan, as it sets the kNN rows' KnnOptions::search_again_distance (LioPpf: only for a scan
  // whose prediction is that near). The patch map must not change within the scan.
  void SetKeepDistance(double metres) { keep_distance_ = metres; }
  // > 0: a pre-fit plane gives at most this many rows, every (count / cap)-th of its points in
  // scan order, each weighted count / cap (PpfConfig::skeleton_rows_per_plane); 0: every point.
  // Needs the pre-fit source.
  void SetRowsPerPlane(int cap) { rows_per_plane_ = cap; }
  std::string Name() const override { return "skeleton"; }
  void BeginScan(const ScanFrame& frame) override;
  void ComputeRows(const Eigen::Isometry3d& T_world_lidar,
                   std::vector<PointPlaneRow>* rows) override;
  TeamWork PrepareRows(const Eigen::Isometry3d& T_world_lidar) override;
  void RowsInTeam() override;
  void FinishRows(const Eigen::Isometry3d& T_world_lidar,
                  std::vector<PointPlaneRow>* rows) override;
  void Reset() override;

  // Matches of the last ComputeRows call (diagnostics and tests).
  const std::vector<SkeletonMatch>& last_matches() const { return matches_; }
  // Appends one AssociatedPoint per skeleton point of the last ComputeRows call (the update's
  // last iteration): covered, with the patch's plane, where a patch of its own surface was found,
  // however far the point lies from it (the gate eps is not applied). The consistency check
  // scores the scan's posterior on these with the kNN rows' own associations, so that in kPpf its
  // fit is of the whole scan and not of the scattered points alone. False (nothing appended)
  // without a patch map or without a ComputeRows call since BeginScan.
  bool AppendAssociations(std::vector<AssociatedPoint>* out) const;

 private:
  void KeepRowsPerPlane();
  // The matching loop over this provider's state at team_T_ (skeleton_residual.cpp).
  SkeletonMatchLoop Loop();

  const SkeletonWindow* window_;
  double eps_;
  const ScanFrame* frame_ = nullptr;
  std::vector<Plane> planes_world_;
  std::vector<int> skeleton_indices_;
  std::vector<SkeletonMatch> matches_;
  std::vector<PatchLookup> lookups_;  // per skeleton_indices_ entry, this scan
  // Per skeleton_indices_ entry: the patch of the last ComputeRows call (nullptr: none).
  std::vector<const PlanePatchMap::Patch*> found_;
  double keep_distance_ = 0.0;
  const PrefitResult* prefit_ = nullptr;
  double normal_gate_deg_ = 0.0;
  const PlanePatchMap* patches_ = nullptr;
  bool window_fallback_ = true;
  std::vector<Eigen::Vector3d> own_normals_;  // per skeleton_indices_ entry, scan frame
  int rows_per_plane_ = 0;
  std::vector<int> plane_of_;  // per scan point: its pre-fit plane, -1 none (scratch)
  std::vector<size_t> per_plane_count_, per_plane_rank_;  // KeepRowsPerPlane's scratch
  std::vector<double> row_weights_;  // per scan point, this scan; empty: every row weighs 1
  int num_threads_ = 0;
  // The pose of the rows being computed, between PrepareRows and FinishRows, and the loop's
  // scratch.
  bool team_ready_ = false;
  Eigen::Isometry3d team_T_ = Eigen::Isometry3d::Identity();
  std::vector<Plane> local_planes_;
  std::vector<SkeletonMatch> per_point_;
};

}  // namespace ppf
