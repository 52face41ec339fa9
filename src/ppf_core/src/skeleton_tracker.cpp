#include "ppf_core/skeleton_tracker.hpp"

namespace ppf {

SkeletonTracker::SkeletonTracker(const PpfConfig& config)
    : prefitter_(config),
      window_(prefitter_.config()),
      provider_(std::make_shared<SkeletonResidualProvider>(
          &window_, prefitter_.config().point_to_plane_thresh)) {
  provider_->SetPrefitSource(&prefit_, prefitter_.config().skeleton_normal_gate_deg);
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

void SkeletonTracker::Finish(const ScanFrame& /*frame*/, const Eigen::Isometry3d& T_world_lidar) {
  last_ids_ = window_.Update(prefit_.planes, T_world_lidar);
}

void SkeletonTracker::Reset() {
  window_.Clear();
  provider_->Reset();
  prefit_ = PrefitResult{};
  last_ids_.clear();
}

}  // namespace ppf
