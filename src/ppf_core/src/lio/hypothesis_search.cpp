#include "ppf_core/lio/hypothesis_search.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ppf_core/lio/voxel_map.hpp"
#include "ppf_core/ppf/plane_patch_map.hpp"

namespace ppf {

ScanFrame SampleFrame(const ScanFrame& frame, int max_points, std::vector<size_t>* kept) {
  ScanFrame s;
  s.stamp_s = frame.stamp_s;
  s.T_world_lidar_predicted = frame.T_world_lidar_predicted;
  s.T_imu_lidar = frame.T_imu_lidar;
  s.map = frame.map;
  s.patches = frame.patches;
  s.residual_max_range = frame.residual_max_range;
  const size_t n = frame.points_lidar.size();
  const size_t stride =
      max_points > 0 ? std::max<size_t>(1, n / static_cast<size_t>(max_points)) : 1;
  s.points_lidar.reserve(n / stride + 1);
  if (kept != nullptr) kept->clear();
  for (size_t i = 0; i < n; i += stride) {
    s.points_lidar.push_back(frame.points_lidar[i]);
    if (kept != nullptr) kept->push_back(i);
  }
  s.labels.assign(s.points_lidar.size(), PointLabel::kScattered);
  return s;
}

namespace {

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

namespace {

// The score and the step from the accumulated rows (n: the points probed, of which `covered`
// met the map and `inliers` lie within the fit gate).
template <int N>
void FinishProbe(long n, long covered, long inliers, long rows, double dt2, double rr,
                 const Eigen::Matrix<double, N, N>& JtJ, const Eigen::Matrix<double, N, 1>& Jtr,
                 const IekfOptions& iekf, PoseProbe* out) {
  using MatN = Eigen::Matrix<double, N, N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  PoseProbe& probe = *out;
  probe.score.inliers = static_cast<size_t>(inliers);
  probe.score.covered = static_cast<size_t>(covered);
  // Too few covered points say nothing (a pose in empty space); 5 % of the scan at least.
  if (covered > 0 && static_cast<double>(covered) >= 0.05 * static_cast<double>(n)) {
    probe.score.fit = static_cast<double>(inliers) / static_cast<double>(covered);
  }
  probe.rows = static_cast<size_t>(rows);
  if (rows < N) return;
  // Only along the directions the rows pin (the IEKF's thresholds): in a corridor the scan says
  // nothing about the position along it, and a pseudo-step there would be noise.
  MatN proj = MatN::Zero();
  auto strong = [](const Eigen::Matrix3d& info, double min_eig) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(info);
    Eigen::Matrix3d p = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 3; ++i) {
      if (es.eigenvalues()(i) >= min_eig) p += es.eigenvectors().col(i) * es.eigenvectors().col(i).transpose();
    }
    return p;
  };
  proj.template block<3, 3>(0, 0) =
      strong(JtJ.template block<3, 3>(0, 0), iekf.degeneracy_min_eig_rotation);
  proj.template block<3, 3>(3, 3) =
      strong(JtJ.template block<3, 3>(3, 3), iekf.degeneracy_min_eig_translation);
  if constexpr (N == 9) {
    // A velocity moves a point by its time from the scan end: the translation's threshold,
    // scaled by the rows' mean squared time, is the same evidence per row.
    proj.template block<3, 3>(6, 6) = strong(JtJ.template block<3, 3>(6, 6),
                                             iekf.degeneracy_min_eig_translation * dt2 / rows);
  }
  const MatN A = proj * JtJ * proj + (MatN::Identity() - proj);
  const VecN step = -A.ldlt().solve(proj * Jtr);
  if (step.allFinite()) {
    probe.step_rot = step.template head<3>();
    probe.step_pos = step.template segment<3>(3);
    if constexpr (N == 9) probe.step_vel = step.template tail<3>();
  }
  // The position step against its own scatter: the rows' squared residuals left after the
  // (linearised) step, per degree of freedom, times the inverse information along the pinned
  // directions. A step of a few rows that disagree among themselves is noise of that size.
  if (step.allFinite() && rows > N) {
    const double left = rr + 2.0 * step.dot(Jtr) + step.dot(JtJ * step);
    const double s2 = std::max(left, 0.0) / static_cast<double>(rows - N);
    const MatN cov = s2 * A.inverse();
    const Eigen::Vector3d dp = probe.step_pos;
    const Eigen::Matrix3d cov_pp =
        cov.template block<3, 3>(3, 3) + 1e-12 * Eigen::Matrix3d::Identity();
    const double z2 = dp.dot(cov_pp.ldlt().solve(dp));
    if (std::isfinite(z2)) probe.step_pos_sigmas = std::sqrt(std::max(z2, 0.0));
  }
}

// The rows of ProbePose, and with point times (dt: seconds from the scan end, per frame point)
// three more columns: the world velocity over the scan, which moves each point by dt times it.
template <int N>
PoseProbe Probe(const ScanFrame& frame, const std::vector<float>* dt,
                const Eigen::Matrix3d& vel_space, const Eigen::Isometry3d& T_world_lidar, const LidarOnlyOptions& options,
                const KnnOptions& knn, const IekfOptions& iekf, double wide_gate) {
  using MatN = Eigen::Matrix<double, N, N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  PoseProbe probe;
  if (frame.points_lidar.empty() || frame.map == nullptr || frame.map->size() == 0) return probe;
  const VoxelMap& map = *frame.map;
  const size_t k = static_cast<size_t>(std::max(3, knn.k));
  const long n = static_cast<long>(frame.points_lidar.size());
  const Eigen::Vector3d c = T_world_lidar.translation();
  long covered = 0, inliers = 0, rows = 0;
  double dt2 = 0.0, rr = 0.0;
  MatN JtJ = MatN::Zero();
  VecN Jtr = VecN::Zero();
#ifdef _OPENMP
  const int threads = knn.num_threads > 0 ? knn.num_threads : omp_get_max_threads();
#endif
#pragma omp parallel num_threads(threads) reduction(+ : covered, inliers, rows, dt2, rr)
  {
    std::vector<Eigen::Vector3f> nn;
    MatN JtJ_t = MatN::Zero();
    VecN Jtr_t = VecN::Zero();
#pragma omp for schedule(dynamic, 256)
    for (long i = 0; i < n; ++i) {
      const Eigen::Vector3d p =
          T_world_lidar * frame.points_lidar[static_cast<size_t>(i)].cast<double>();
      Eigen::Vector3d normal;
      double d;
      if (map.GetClosest(p.cast<float>(), k, knn.max_neighbor_distance, &nn) >= k) {
        ++covered;
        if (!FitPlane(nn, knn.plane_threshold, &normal, &d, knn.min_plane_spread)) continue;
      } else {
        const PlanePatchMap::Patch* patch =
            frame.patches != nullptr ? frame.patches->Find(p, Eigen::Vector3d::UnitZ(), 0.0)
                                     : nullptr;
        if (patch == nullptr) continue;
        ++covered;
        normal = patch->plane.n;
        d = patch->plane.d;
      }
      const double r = normal.dot(p) + d;
      if (std::abs(r) < options.fit_gate) ++inliers;
      if (!(std::abs(r) < wide_gate)) continue;
      ++rows;
      VecN j;
      j.template head<3>() = (p - c).cross(normal);
      j.template segment<3>(3) = normal;
      if constexpr (N == 9) {
        const double t = (*dt)[static_cast<size_t>(i)];
        j.template tail<3>() = t * (vel_space * normal);
        dt2 += t * t;
      }
      JtJ_t.noalias() += j * j.transpose();
      Jtr_t.noalias() += j * r;
      rr += r * r;
    }
#pragma omp critical
    {
      JtJ += JtJ_t;
      Jtr += Jtr_t;
    }
  }
  FinishProbe<N>(n, covered, inliers, rows, dt2, rr, JtJ, Jtr, iekf, &probe);
  return probe;
}

}  // namespace

PoseProbe ProbePose(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                    const LidarOnlyOptions& options, const KnnOptions& knn,
                    const IekfOptions& iekf, double wide_gate) {
  return Probe<6>(frame, nullptr, Eigen::Matrix3d::Zero(), T_world_lidar, options, knn, iekf,
                  wide_gate);
}

PoseProbe ProbePoseAndVelocity(const ScanFrame& frame, const std::vector<float>& dt,
                               const Eigen::Vector3d& fixed_axis,
                               const Eigen::Isometry3d& T_world_lidar,
                               const LidarOnlyOptions& options, const KnnOptions& knn,
                               const IekfOptions& iekf, double wide_gate) {
  if (dt.size() != frame.points_lidar.size()) return PoseProbe();
  const Eigen::Vector3d u = fixed_axis.norm() > 0.0 ? fixed_axis.normalized() : fixed_axis;
  const Eigen::Matrix3d space = Eigen::Matrix3d::Identity() - u * u.transpose();
  return Probe<9>(frame, &dt, space, T_world_lidar, options, knn, iekf, wide_gate);
}

PoseProbe ProbePoseAssociated(const std::vector<AssociatedPoint>& points,
                              const Eigen::Isometry3d& T_world_lidar,
                              const LidarOnlyOptions& options, const IekfOptions& iekf,
                              double wide_gate, size_t step_points) {
  PoseProbe probe;
  const Eigen::Vector3d c = T_world_lidar.translation();
  long covered = 0, inliers = 0, rows = 0;
  double rr = 0.0;
  Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> Jtr = Eigen::Matrix<double, 6, 1>::Zero();
  for (size_t i = 0; i < points.size(); ++i) {
    const AssociatedPoint& a = points[i];
    if (!a.covered) continue;
    ++covered;
    if (!a.has_plane) continue;
    const Eigen::Vector3d p = T_world_lidar * a.point_lidar.cast<double>();
    const double r = a.normal.dot(p) + a.d;
    if (std::abs(r) < options.fit_gate) ++inliers;
    if (i >= step_points || !(std::abs(r) < wide_gate)) continue;
    ++rows;
    Eigen::Matrix<double, 6, 1> j;
    j.head<3>() = (p - c).cross(a.normal);
    j.tail<3>() = a.normal;
    JtJ.noalias() += j * j.transpose();
    Jtr.noalias() += j * r;
    rr += r * r;
  }
  FinishProbe<6>(static_cast<long>(points.size()), covered, inliers, rows, 0.0, rr, JtJ, Jtr, iekf,
                 &probe);
  return probe;
}

FitScore ScoreFit(const ScanFrame& frame, const Eigen::Isometry3d& T_world_lidar,
                  const LidarOnlyOptions& options, const KnnOptions& knn) {
  // A zero-wide gate takes no row: the same neighbours and planes, no step.
  return ProbePose(frame, T_world_lidar, options, knn, IekfOptions(), 0.0).score;
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

  const ScanFrame sample = SampleFrame(frame, options.coarse_points);
  IekfOptions coarse = iekf;
  coarse.max_iterations = std::max(1, options.coarse_iterations);
  // The refined gate would drop the true matches of a guess that is still far off.
  coarse.refined_gate = 0.0;
  KnnOptions wide = knn;
  wide.max_residual = std::max(knn.max_residual, options.coarse_max_residual);
  KnnResidualProvider provider(wide);
  // Many guesses (a re-localization along a street after a long gap): a quick pass on a quarter
  // of the sample with a few iterations ranks them, and only the best few are aligned in full,
  // best first. Each full alignment costs as much as the whole quick pass over a dozen guesses,
  // and a scan that takes seconds makes a node drop the scans after it.
  constexpr size_t kScreenAbove = 16;
  constexpr size_t kKeepAfterScreen = 4;
  std::vector<size_t> order(hypotheses.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  if (hypotheses.size() > kScreenAbove) {
    const ScanFrame quick_sample = SampleFrame(frame, std::max(1, options.coarse_points / 4));
    IekfOptions quick = coarse;
    quick.max_iterations = std::min(coarse.max_iterations, 3);
    std::vector<std::pair<size_t, size_t>> ranked;  // (inliers, index)
    for (size_t i = 0; i < hypotheses.size(); ++i) {
      NavState s = StateAt(hypotheses[i].T_world_lidar, quick_sample.T_imu_lidar);
      provider.BeginScan(quick_sample);
      IekfUpdate(quick, quick_sample.T_imu_lidar, {&provider}, &s);
      const FitScore score =
          ScoreFit(quick_sample, s.T_world_imu() * quick_sample.T_imu_lidar, options, knn);
      ranked.emplace_back(score.inliers, i);
    }
    const size_t keep = std::min(kKeepAfterScreen, ranked.size());
    std::stable_sort(ranked.begin(), ranked.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    order.clear();
    for (size_t k = 0; k < keep; ++k) order.push_back(ranked[k].second);
    best.tried += static_cast<int>(hypotheses.size() - keep);
  }
  size_t best_inliers = 0;
  bool have = false;
  for (size_t i : order) {
    NavState s = StateAt(hypotheses[i].T_world_lidar, sample.T_imu_lidar);
    provider.BeginScan(sample);
    IekfUpdate(coarse, sample.T_imu_lidar, {&provider}, &s);
    const Eigen::Isometry3d T = s.T_world_imu() * sample.T_imu_lidar;
    const FitScore score = ScoreFit(sample, T, options, knn);
    ++best.tried;
    // The guess that explains the most points wins; the ratio only says whether to look further.
    if (!have || score.inliers > best_inliers) {
      have = true;
      best_inliers = score.inliers;
      best.fit = score.fit;
      best.T_world_lidar = T;
      best.name = hypotheses[i].name;
    }
    if (score.fit >= options.good_fit) break;
  }
  return best;
}

}  // namespace ppf
