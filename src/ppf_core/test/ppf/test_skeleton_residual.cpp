#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/ppf/skeleton_residual.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"

namespace ppf {
namespace {

TEST(PpfSkeletonResidual, NearestWindowPlaneWithinGate) {
  const std::vector<Plane> window = {Plane{Eigen::Vector3d::UnitZ(), 0.0},    // ground
                                     Plane{Eigen::Vector3d::UnitX(), -5.0}};  // wall x = 5
  const std::vector<Eigen::Vector3f> pts = {
      {1, 0, 0.05f},     // 0: ground, 0.05
      {4.9f, 0, 3},      // 1: wall, -0.1
      {4.9f, 0, 0.15f},  // 2: both near; wall is nearer (0.1 < 0.15)
      {2, 0, 0.3f},      // 3: beyond eps of everything
      {1, 0, -0.19f},    // 4: just inside the gate
      {7, 7, 7}};        // 5: not a skeleton point (not listed)
  std::vector<SkeletonMatch> m;
  ComputeSkeletonMatches(pts, {0, 1, 2, 3, 4}, Eigen::Isometry3d::Identity(), window, 0.2, &m);
  ASSERT_EQ(m.size(), 4u);
  EXPECT_EQ(m[0].point_index, 0);
  EXPECT_EQ(m[0].plane_index, 0);
  EXPECT_NEAR(m[0].signed_distance, 0.05, 1e-6);
  EXPECT_EQ(m[1].point_index, 1);
  EXPECT_EQ(m[1].plane_index, 1);
  EXPECT_NEAR(m[1].signed_distance, -0.1, 1e-6);
  EXPECT_EQ(m[2].point_index, 2);
  EXPECT_EQ(m[2].plane_index, 1);
  EXPECT_EQ(m[3].point_index, 4);
  EXPECT_NEAR(m[3].signed_distance, -0.19, 1e-6);
  // Empty window or non-positive gate: no matches, no crash.
  ComputeSkeletonMatches(pts, {0, 1}, Eigen::Isometry3d::Identity(), {}, 0.2, &m);
  EXPECT_TRUE(m.empty());
  ComputeSkeletonMatches(pts, {0, 99, -1}, Eigen::Isometry3d::Identity(), window, 0.2, &m);
  EXPECT_EQ(m.size(), 1u);  // out-of-range indices ignored
}

TEST(PpfSkeletonResidual, UsesThePoseAndKeepsNoStaleMatches) {
  const std::vector<Plane> window = {Plane{Eigen::Vector3d::UnitZ(), 0.0}};
  const std::vector<Eigen::Vector3f> pts = {{0, 0, 0.0f}, {3, 0, 0.0f}};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::vector<SkeletonMatch> m;
  ComputeSkeletonMatches(pts, {0, 1}, T, window, 0.2, &m);
  EXPECT_EQ(m.size(), 2u);
  T.translation().z() = 0.5;  // the estimate moved away: no point may keep its earlier match
  ComputeSkeletonMatches(pts, {0, 1}, T, window, 0.2, &m);
  EXPECT_TRUE(m.empty());
  T.translation().z() = 0.1;
  ComputeSkeletonMatches(pts, {0, 1}, T, window, 0.2, &m);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_NEAR(m[0].signed_distance, 0.1, 1e-9);
}

TEST(PpfSkeletonResidual, NormalGateRejectsMatchesToPerpendicularPlanes) {
  // The window knows only the floor; a new wall (x = 5) was fitted in this scan. Its foot points
  // lie within eps of the floor and would be matched to it by Eq. 10 alone.
  const std::vector<Plane> window = {Plane{Eigen::Vector3d::UnitZ(), 0.0}};
  const std::vector<Eigen::Vector3f> pts = {{5, 0, 0.15f}, {5, 1, 0.1f}, {2, 0, 0.05f}};
  const std::vector<int> idx = {0, 1, 2};
  const std::vector<Eigen::Vector3d> own = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitX(),
                                            Eigen::Vector3d::UnitZ()};  // wall, wall, floor
  std::vector<SkeletonMatch> m;
  ComputeSkeletonMatches(pts, idx, Eigen::Isometry3d::Identity(), window, 0.2, &m);
  EXPECT_EQ(m.size(), 3u);  // no gate: the wall's foot matches the floor
  ComputeSkeletonMatches(pts, idx, own, 10.0, Eigen::Isometry3d::Identity(), window, 0.2, &m);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0].point_index, 2);
  // The gate compares normals in the same frame: a rotated pose rotates the window plane.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
  ComputeSkeletonMatches(pts, idx, own, 10.0, T, window, 0.2, &m);
  for (const SkeletonMatch& x : m) EXPECT_NE(x.point_index, 2);  // floor normal now off by 90
  // Mismatched normal list (e.g. a custom splitter): gate skipped rather than misapplied.
  ComputeSkeletonMatches(pts, idx, {Eigen::Vector3d::UnitX()}, 10.0, Eigen::Isometry3d::Identity(),
                         window, 0.2, &m);
  EXPECT_EQ(m.size(), 3u);
}

TEST(PpfSkeletonResidual, ProviderRowsReproduceEquationTen) {
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  FittedPlane ground;
  ground.plane = Plane{Eigen::Vector3d::UnitZ(), 1.5};  // z = -1.5 in the LiDAR frame
  ground.centroid = Eigen::Vector3d(3, 0, -1.5);
  ground.num_inliers = 1000;
  Eigen::Isometry3d T_world_prev = Eigen::Isometry3d::Identity();
  T_world_prev.translation() = Eigen::Vector3d(10, 0, 1.5);  // ground is z = 0 in the world
  window.Update({ground}, T_world_prev);

  ScanFrame frame;
  frame.points_lidar = {{1, 0, -1.45f}, {2, 1, -1.6f}, {3, 0, 0.5f}, {4, 0, -1.5f}};
  frame.labels = {PointLabel::kSkeleton, PointLabel::kSkeleton, PointLabel::kSkeleton,
                  PointLabel::kScattered};
  SkeletonResidualProvider provider(&window, cfg.point_to_plane_thresh);
  provider.BeginScan(frame);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(11, 0, 1.5);
  std::vector<PointPlaneRow> rows;
  provider.ComputeRows(T, &rows);
  ASSERT_EQ(rows.size(), 2u);  // point 2 is 2 m off; point 3 is scattered (kNN's job)
  for (const PointPlaneRow& row : rows) {
    const double r = row.normal_world.dot(T * row.point_lidar) + row.offset;
    EXPECT_LT(std::abs(r), 0.2);
    EXPECT_NEAR(row.normal_world.norm(), 1.0, 1e-12);
  }
  EXPECT_NEAR(rows[0].normal_world.dot(T * rows[0].point_lidar) + rows[0].offset, 0.05, 1e-6);
  // The window is read at BeginScan: updating it mid-scan does not change this scan's rows.
  window.Clear();
  rows.clear();
  provider.ComputeRows(T, &rows);
  EXPECT_EQ(rows.size(), 2u);
}

}  // namespace
}  // namespace ppf
