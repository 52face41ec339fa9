// Skeleton tracking (paper Sec. IV-B, Fig. 2): plane pre-fitting wired into the LIO pipeline.
//
// Per scan (the facade calls these in kPpf mode; residual_provider.hpp shows where):
//   Split   (before the update)  window planes -> guesses at the IMU-predicted pose; pre-fit the
//                                scan; label Omega kSkeleton, semi-inliers kDiscarded, Theta
//                                kScattered (only those enter the kNN map).
//   rows    (every IEKF iter.)   SkeletonResidualProvider: Omega against the plane patch map
//                                (anchor_patches) or else the window F as it was before this
//                                scan (Eq. 10), recomputed at every iteration.
//   Finish  (after the update)   this scan's planes -> world with the converged pose -> window
//                                (track association keeps ids stable); Omega -> patch map.
//   Reset   a filter reset: window, patch map and tracks start empty.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "ppf_core/ppf/plane_patch_map.hpp"
#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf_config.hpp"
#include "ppf_core/lio/residual_provider.hpp"
#include "ppf_core/ppf/skeleton_residual.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"

namespace ppf {

class SkeletonTracker {
 public:
  explicit SkeletonTracker(const PpfConfig& config);

  // Set frame->labels (pre-filled with kScattered) without resizing points_lidar.
  void Split(ScanFrame* frame);
  // After the update, with the converged pose: this scan's planes to the world (the window), and
  // its skeleton points into the patch map unless extend_map is false (a pose not yet confirmed).
  void Finish(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
              bool extend_map = true);
  void Reset();

  // The skeleton residual provider reading this tracker's window (the IEKF's second source).
  std::shared_ptr<ResidualProvider> residual_provider() const { return provider_; }
  const SkeletonResidualProvider& skeleton_provider() const { return *provider_; }
  // SkeletonResidualProvider::SetKeepDistance for the scans from now on.
  void SetKeepDistance(double metres) { provider_->SetKeepDistance(metres); }

  const PpfConfig& config() const { return prefitter_.config(); }
  const SkeletonWindow& window() const { return window_; }
  const PlanePatchMap& patch_map() const { return patches_; }
  const PrefitResult& last_prefit() const { return prefit_; }  // of the last Split
  // Track ids of the last Finish, one per plane of last_prefit().planes.
  const std::vector<int64_t>& last_track_ids() const { return last_ids_; }

 private:
  PlanePrefitter prefitter_;
  SkeletonWindow window_;
  PlanePatchMap patches_;
  int scans_since_prune_ = 0;
  std::shared_ptr<SkeletonResidualProvider> provider_;
  PrefitResult prefit_;
  std::vector<int64_t> last_ids_;
  std::vector<Eigen::Vector3d> normals_world_;  // scratch of Finish: each plane's world normal
};

}  // namespace ppf
