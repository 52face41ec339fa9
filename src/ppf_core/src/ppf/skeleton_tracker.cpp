#include "ppf_core/ppf/skeleton_tracker.hpp"

namespace ppf {
namespace {

PlanePatchMapOptions PatchOptions(const PpfConfig& c) {
  PlanePatchMapOptions o;
  o.cell_size = c.patch_size;
  o.max_points = c.patch_max_points;
  return o;
}

}  // namespace

SkeletonTracker::SkeletonTracker(const PpfConfig& config)
    : prefitter_(config),
      window_(prefitter_.config()),
      patches_(PatchOptions(prefitter_.config())),
      provider_(std::make_shared<SkeletonResidualProvider>(
          &window_, prefitter_.config().point_to_plane_thresh)) {
  provider_->SetPrefitSource(&prefit_, prefitter_.config().skeleton_normal_gate_deg);
  provider_->SetNumThreads(prefitter_.config().num_threads);
  provider_->SetRowsPerPlane(prefitter_.config().skeleton_rows_per_plane);
  if (prefitter_.config().anchor_patches) {
    provider_->SetPatchMap(&patches_, prefitter_.config().patch_window_fallback);
  }
}

void SkeletonTracker::Split(ScanFrame* frame) {
  const std::vector<PlaneGuess> guesses =
      config().incremental_fitting ? window_.GuessesInFrame(frame->T_world_lidar_predicted)
                                   : std::vector<PlaneGuess>{};
  prefitter_.Fit(frame->points_lidar, guesses, &prefit_);
  frame->labels.assign(frame->points_lidar.size(), PointLabel::kScattered);
  for (int i : prefit_.skeleton_indices) frame->labels[i] = PointLabel::kSkeleton;
  for (int i : prefit_.discarded_indices) frame->labels[i] = PointLabel::kDiscarded;
}

void SkeletonTracker::Finish(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                             bool extend_map) {
  last_ids_ = window_.Update(prefit_.planes, T_world_lidar);
  if (!config().anchor_patches || !extend_map) return;
  const size_t n = std::min(prefit_.skeleton_indices.size(), prefit_.skeleton_plane.size());
  // Each plane's normal in the world once, not once per point of it (the same product).
  normals_world_.clear();
  for (const FittedPlane& f : prefit_.planes) {
    normals_world_.push_back(T_world_lidar.linear() * f.plane.n);
  }
  PlanePatchMap::InsertHint hint;
  for (size_t k = 0; k < n; ++k) {
    const int idx = prefit_.skeleton_indices[k];
    const int pl = prefit_.skeleton_plane[k];
    if (idx < 0 || idx >= static_cast<int>(frame.points_lidar.size()) || pl < 0 ||
        pl >= static_cast<int>(prefit_.planes.size())) {
      continue;
    }
    patches_.Insert(T_world_lidar * frame.points_lidar[idx].cast<double>(), normals_world_[pl],
                    &hint);
  }
  patches_.FinishInsert();
  if (config().patch_radius > 0.0 && ++scans_since_prune_ >= 10) {
    patches_.RemoveFarFrom(T_world_lidar.translation(), config().patch_radius);
    scans_since_prune_ = 0;
  }
}

void SkeletonTracker::Reset() {
  window_.Clear();
  patches_.Clear();
  provider_->Reset();
  prefit_ = PrefitResult{};
  last_ids_.clear();
}

}  // namespace ppf
