#include "ppf_core/hypothesis_search.hpp"

#include <algorithm>

namespace ppf {
namespace {

ScanFrame Sample(const ScanFrame& frame, int max_points) {
  ScanFrame s = frame;
  const size_t n = frame.points_lidar.size();
  const size_t stride = max_points > 0 ? std::max<size_t>(1, n / static_cast<size_t>(max_points)) : 1;
  s.points_lidar.clear();
  for (size_t i = 0; i < n; i += stride) s.points_lidar.push_back(frame.points_lidar[i]);
  s.labels.assign(s.points_lidar.size(), PointLabel::kScattered);
  return s;
}

NavState StateAt(const Eigen::Isometry3d& T_world_lidar, const Eigen::Isometry3d& T_imu_lidar) {
  NavState s;
  const Eigen::Isometry3d T = T_world_lidar * T_imu_lidar.inverse();
  s.R_world_imu = T.linear();
  s.p_world_imu = T.translation();
  // A weak prior: the guess is only where the search starts, the scan decides.
  s.P = StateCov::Identity() * 1e-6;
  s.P.block<3, 3>(kRot, kRot) = Eigen::Matrix3d::Identity();
  s.P.block<3, 3>(kPos, kPos) = Eigen::Matrix3d::Identity() * 4.0;
  return s;
}

}  // namespace

double ScanFit(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
               const LidarOnlyOptions& options, const KnnOptions& knn) {
  if (frame.points_lidar.empty() || frame.map == nullptr) return 0.0;
  ScanFrame all = frame;
  all.labels.assign(all.points_lidar.size(), PointLabel::kScattered);
  KnnOptions gate = knn;
  gate.max_residual = options.fit_gate;
  KnnResidualProvider score(gate);
  score.BeginScan(all);
  std::vector<PointPlaneRow> rows;
  score.ComputeRows(T_world_lidar, &rows);
  return static_cast<double>(rows.size()) / static_cast<double>(all.points_lidar.size());
}

CoarseAlignment AlignHypotheses(const ScanFrame& frame,
                                const std::vector<MotionHypothesis>& hypotheses,
                                const LidarOnlyOptions& options, const IekfOptions& iekf,
                                const KnnOptions& knn) {
  CoarseAlignment best;
  if (hypotheses.empty()) return best;
  best.T_world_lidar = hypotheses.front().T_world_lidar;
  best.name = hypotheses.front().name;
  if (frame.points_lidar.empty() || frame.map == nullptr) return best;

  const ScanFrame sample = Sample(frame, options.coarse_points);
  IekfOptions coarse = iekf;
  coarse.max_iterations = std::max(1, options.coarse_iterations);
  // The refined gate would drop the true matches of a guess that is still far off.
  coarse.refined_gate = 0.0;
  KnnOptions wide = knn;
  wide.max_residual = std::max(knn.max_residual, options.coarse_max_residual);
  KnnResidualProvider provider(wide);
  best.fit = -1.0;
  for (size_t i = 0; i < hypotheses.size(); ++i) {
    NavState s = StateAt(hypotheses[i].T_world_lidar, sample.T_imu_lidar);
    provider.BeginScan(sample);
    IekfUpdate(coarse, sample.T_imu_lidar, {&provider}, &s);
    const Eigen::Isometry3d T = s.T_world_imu() * sample.T_imu_lidar;
    const double fit = ScanFit(sample, T, options, knn);
    ++best.tried;
    if (fit > best.fit) {
      best.fit = fit;
      best.T_world_lidar = T;
      best.name = hypotheses[i].name;
    }
    if (i == 0 && fit >= options.good_fit) break;
  }
  return best;
}

}  // namespace ppf
