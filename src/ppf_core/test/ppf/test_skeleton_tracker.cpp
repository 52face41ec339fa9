#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/lio/hypothesis_search.hpp"
#include "ppf_core/lio/knn_residual.hpp"
#include "ppf_core/ppf/skeleton_tracker.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

ScanFrame MakeFrame(const Eigen::Isometry3d& T_world_lidar, unsigned seed) {
  const test::CornerScene world = test::MakeCornerScene(0.02, 400, seed);
  ScanFrame f;
  for (const auto& p : world.points) {
    f.points_lidar.push_back((T_world_lidar.inverse() * p.cast<double>()).cast<float>());
  }
  f.labels.assign(f.points_lidar.size(), PointLabel::kScattered);
  f.T_world_lidar_predicted = T_world_lidar;
  return f;
}

Eigen::Isometry3d PoseAt(int scan) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.02 * scan, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.5 * scan, 0.0, 0.0);
  return T;
}

TEST(PpfTracker, LabelsRowsAndWindowThroughTheHooks) {
  PpfConfig cfg = PpfConfigForBeams(64);
  cfg.plane_least_inliers = 150;
  // Points in cells the patch map has not seen yet fall back to the window: every skeleton point
  // can be matched (without the fallback those ~10 % give no residual).
  cfg.patch_window_fallback = true;
  cfg.skeleton_rows_per_plane = 256;  // the planes here hold more points: rows are capped
  SkeletonTracker tracker(cfg);
  auto provider = tracker.residual_provider();
  std::map<size_t, int64_t> first_ids;
  for (int scan = 0; scan < 4; ++scan) {
    ScanFrame frame = MakeFrame(PoseAt(scan), 50 + scan);
    tracker.Split(&frame);
    ASSERT_EQ(frame.labels.size(), frame.points_lidar.size());
    size_t skeleton = 0, scattered = 0, discarded = 0;
    for (PointLabel l : frame.labels) {
      skeleton += l == PointLabel::kSkeleton;
      scattered += l == PointLabel::kScattered;
      discarded += l == PointLabel::kDiscarded;
    }
    EXPECT_EQ(skeleton, tracker.last_prefit().skeleton_indices.size());
    EXPECT_EQ(scattered, tracker.last_prefit().scattered_indices.size());
    EXPECT_EQ(discarded, tracker.last_prefit().discarded_indices.size());
    EXPECT_GT(skeleton, frame.points_lidar.size() / 2);  // walls and ground dominate

    provider->BeginScan(frame);
    std::vector<PointPlaneRow> rows;
    provider->ComputeRows(PoseAt(scan), &rows);
    if (scan == 0) {
      EXPECT_TRUE(rows.empty());  // empty window: nothing to match yet
    } else {
      // With the patch map and the window from the previous scans nearly every skeleton point is
      // matched (a plane gives at most skeleton_rows_per_plane rows, weighted to stand for all of
      // its points), and at the true pose every residual is small: within delta of its own plane,
      // plus the small difference between this scan's fit and the earlier ones.
      double weight = 0.0;
      for (const PointPlaneRow& row : rows) weight += row.weight;
      EXPECT_LE(rows.size(), 3u * static_cast<size_t>(cfg.skeleton_rows_per_plane));
      EXPECT_GT(weight, 0.9 * static_cast<double>(skeleton));
      for (const PointPlaneRow& row : rows) {
        ASSERT_LT(std::abs(row.normal_world.dot(PoseAt(scan) * row.point_lidar) + row.offset),
                  cfg.delta + 0.02);
      }
      EXPECT_EQ(tracker.last_prefit().guesses_accepted, 3);
    }
    provider->EndScan(PoseAt(scan));
    tracker.Finish(frame, PoseAt(scan));
    ASSERT_EQ(tracker.last_track_ids().size(), tracker.last_prefit().planes.size());
    EXPECT_EQ(tracker.window().planes().size(), 3u);
    if (scan == 0) {
      for (size_t i = 0; i < tracker.last_track_ids().size(); ++i) {
        first_ids[i] = tracker.last_track_ids()[i];
      }
    } else {
      // Guess order follows the window, so the same planes come back under the same ids.
      std::vector<int64_t> now = tracker.last_track_ids(), before;
      for (auto& kv : first_ids) before.push_back(kv.second);
      std::sort(now.begin(), now.end());
      std::sort(before.begin(), before.end());
      EXPECT_EQ(now, before);
    }
  }
  EXPECT_GT(tracker.patch_map().num_patches(), 0u);
  tracker.Reset();
  EXPECT_TRUE(tracker.window().empty());
  EXPECT_EQ(tracker.patch_map().num_cells(), 0u);
}

// The consistency check scores a kPpf scan on its skeleton points too: each with the patch of its
// surface from the last ComputeRows, scored again at any pose (ProbePoseAssociated).
TEST(PpfTracker, SkeletonAssociationsScoreAPoseOnThePatches) {
  PpfConfig cfg = PpfConfigForBeams(64);
  cfg.plane_least_inliers = 150;
  SkeletonTracker tracker(cfg);
  const SkeletonResidualProvider& provider = tracker.skeleton_provider();
  for (unsigned seed : {50u, 51u, 52u}) {
    ScanFrame before = MakeFrame(PoseAt(0), seed);
    tracker.Split(&before);
    tracker.Finish(before, PoseAt(0));
  }
  // The same place seen again (other noise): the cells the first scan filled.
  ScanFrame frame = MakeFrame(PoseAt(0), 53);
  tracker.Split(&frame);
  tracker.residual_provider()->BeginScan(frame);
  std::vector<AssociatedPoint> associated;
  EXPECT_FALSE(provider.AppendAssociations(&associated));  // no ComputeRows since BeginScan
  std::vector<PointPlaneRow> rows;
  tracker.residual_provider()->ComputeRows(PoseAt(0), &rows);
  ASSERT_TRUE(provider.AppendAssociations(&associated));
  const size_t skeleton = tracker.last_prefit().skeleton_indices.size();
  ASSERT_EQ(associated.size(), skeleton);
  const size_t covered = static_cast<size_t>(std::count_if(
      associated.begin(), associated.end(), [](const AssociatedPoint& a) { return a.covered; }));
  EXPECT_GT(covered, 9 * skeleton / 10);
  EXPECT_GE(covered, rows.size());  // a row is a covered point within the gate
  // At the pose: the points lie on their patches. Turned by 5 degrees: many do not.
  const PoseProbe at =
      ProbePoseAssociated(associated, PoseAt(0), LidarOnlyOptions(), IekfOptions(), 1.0);
  Eigen::Isometry3d turned = PoseAt(0);
  turned.linear() =
      Eigen::AngleAxisd(5.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()) * turned.linear();
  const PoseProbe off =
      ProbePoseAssociated(associated, turned, LidarOnlyOptions(), IekfOptions(), 1.0);
  EXPECT_GT(at.score.fit, 0.95);
  // Below what the check calls a poor fit against recent scans that fit as this one does.
  EXPECT_LT(off.score.fit, ConsistencyOptions().fit_ratio * at.score.fit);
  EXPECT_EQ(off.score.covered, at.score.covered);
}

}  // namespace
}  // namespace ppf
