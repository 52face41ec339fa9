#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/ppf/plane_prefitter.hpp"
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

// The normal equations' pose block of rows at T (the IEKF's J = [p x R^T n, n], weighted).
Eigen::Matrix<double, 6, 6> WeightedJtJ(const std::vector<PointPlaneRow>& rows,
                                        const Eigen::Isometry3d& T, double* weight_sum) {
  Eigen::Matrix<double, 6, 6> JtJ = Eigen::Matrix<double, 6, 6>::Zero();
  *weight_sum = 0.0;
  for (const PointPlaneRow& row : rows) {
    Eigen::Matrix<double, 6, 1> j;
    j.head<3>() = row.point_lidar.cross(T.linear().transpose() * row.normal_world);
    j.tail<3>() = row.normal_world;
    JtJ += row.weight * j * j.transpose();
    *weight_sum += row.weight;
  }
  return JtJ;
}

TEST(PpfSkeletonResidual, RowsPerPlaneKeepTheSpreadAndTheInformation) {
  // A ground of 1000 points (z = -1.5 in the LiDAR frame) and a wall of 90 (x = 6), both in the
  // window, the pre-fit of this scan saying which point lies on which.
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  FittedPlane ground, wall;
  ground.plane = Plane{Eigen::Vector3d::UnitZ(), 1.5};
  ground.centroid = Eigen::Vector3d(5, 0, -1.5);
  ground.num_inliers = 1000;
  wall.plane = Plane{-Eigen::Vector3d::UnitX(), 6.0};
  wall.centroid = Eigen::Vector3d(6, 0, 1);
  wall.num_inliers = 90;
  window.Update({ground, wall}, Eigen::Isometry3d::Identity());

  ScanFrame frame;
  PrefitResult prefit;
  prefit.planes = {ground, wall};
  for (int i = 0; i < 1000; ++i) {  // the ground in scan order: rings of 40 points, 2 to 10 m
    const double a = 2.0 * M_PI * (i % 40) / 40.0, r = 2.0 + 8.0 * (i / 40) / 24.0;
    frame.points_lidar.emplace_back(r * std::cos(a), r * std::sin(a), -1.5 + 0.01 * (i % 3));
    prefit.skeleton_plane.push_back(0);
  }
  for (int i = 0; i < 90; ++i) {  // the wall: 6 m by 3 m
    frame.points_lidar.emplace_back(6.0f, -3.0f + 0.2f * (i % 30), -1.0f + 1.0f * (i / 30));
    prefit.skeleton_plane.push_back(1);
  }
  for (size_t k = 0; k < frame.points_lidar.size(); ++k) {
    prefit.skeleton_indices.push_back(static_cast<int>(k));
  }
  frame.labels.assign(frame.points_lidar.size(), PointLabel::kSkeleton);
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();

  SkeletonResidualProvider all(&window, cfg.point_to_plane_thresh);
  all.SetPrefitSource(&prefit, cfg.skeleton_normal_gate_deg);
  all.BeginScan(frame);
  std::vector<PointPlaneRow> full;
  all.ComputeRows(T, &full);
  ASSERT_EQ(full.size(), frame.points_lidar.size());  // every point is on its plane

  SkeletonResidualProvider capped(&window, cfg.point_to_plane_thresh);
  capped.SetPrefitSource(&prefit, cfg.skeleton_normal_gate_deg);
  capped.SetRowsPerPlane(200);
  capped.BeginScan(frame);
  std::vector<PointPlaneRow> rows;
  capped.ComputeRows(T, &rows);
  // The ground gives exactly 200 rows of weight 1000 / 200; the wall, under the cap, all 90 of
  // weight 1.
  size_t ground_rows = 0, wall_rows = 0;
  for (const PointPlaneRow& row : rows) {
    if (row.normal_world.z() > 0.5) {
      ++ground_rows;
      EXPECT_DOUBLE_EQ(row.weight, 5.0);
    } else {
      ++wall_rows;
      EXPECT_DOUBLE_EQ(row.weight, 1.0);
    }
  }
  EXPECT_EQ(ground_rows, 200u);
  EXPECT_EQ(wall_rows, 90u);
  // The ground's rows still span its whole extent (every fifth point, not the first 200).
  double max_range = 0.0;
  for (const PointPlaneRow& row : rows) {
    if (row.normal_world.z() > 0.5) {
      max_range = std::max(max_range, row.point_lidar.head<2>().norm());
    }
  }
  EXPECT_GT(max_range, 9.5);
  // Same information: the weighted normal equations of the kept rows are those of all rows
  // within a few percent, entry by entry relative to the largest.
  double w_full = 0.0, w_capped = 0.0;
  const Eigen::Matrix<double, 6, 6> H_full = WeightedJtJ(full, T, &w_full);
  const Eigen::Matrix<double, 6, 6> H_capped = WeightedJtJ(rows, T, &w_capped);
  EXPECT_NEAR(w_capped, w_full, 1e-9);
  EXPECT_LT((H_capped - H_full).cwiseAbs().maxCoeff(), 0.03 * H_full.cwiseAbs().maxCoeff());
  // Labels the pre-fit does not explain (a custom splitter): no cap, every point a row.
  frame.labels.push_back(PointLabel::kSkeleton);
  frame.points_lidar.emplace_back(3.0f, 0.0f, -1.5f);
  capped.BeginScan(frame);
  rows.clear();
  capped.ComputeRows(T, &rows);
  EXPECT_EQ(rows.size(), frame.points_lidar.size());
}

// The IEKF runs its providers' per-point loops in one team (ResidualProvider::PrepareRows): two
// providers sharing a team of two threads give each the rows its own ComputeRows gives, bit for
// bit and in order, also with matches kept between calls and with a row cap.
TEST(PpfSkeletonResidual, RowsOfASharedTeamAreThoseOfComputeRows) {
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  FittedPlane ground, wall;
  ground.plane = Plane{Eigen::Vector3d::UnitZ(), 1.5};
  ground.centroid = Eigen::Vector3d(5, 0, -1.5);
  ground.num_inliers = 3000;
  wall.plane = Plane{-Eigen::Vector3d::UnitX(), 6.0};
  wall.centroid = Eigen::Vector3d(6, 0, 1);
  wall.num_inliers = 600;
  window.Update({ground, wall}, Eigen::Isometry3d::Identity());
  ScanFrame frame;
  PrefitResult prefit;
  prefit.planes = {ground, wall};
  // Enough points for the team to share out in chunks; every seventh 0.3 m off its plane (no row).
  for (int i = 0; i < 3000; ++i) {
    const double a = 2.0 * M_PI * (i % 100) / 100.0, r = 2.0 + 8.0 * (i / 100) / 30.0;
    const double off = i % 7 == 0 ? 0.3 : 0.01 * (i % 3);
    frame.points_lidar.emplace_back(r * std::cos(a), r * std::sin(a), -1.5 + off);
    prefit.skeleton_plane.push_back(0);
  }
  for (int i = 0; i < 600; ++i) {
    frame.points_lidar.emplace_back(6.0f - (i % 7 == 0 ? 0.3f : 0.0f), -3.0f + 0.1f * (i % 60),
                                    -1.0f + 0.3f * (i / 60));
    prefit.skeleton_plane.push_back(1);
  }
  for (size_t k = 0; k < frame.points_lidar.size(); ++k) {
    prefit.skeleton_indices.push_back(static_cast<int>(k));
  }
  frame.labels.assign(frame.points_lidar.size(), PointLabel::kSkeleton);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.02, -0.01, 0.03);
  T.linear() = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();

  SkeletonResidualProvider a(&window, cfg.point_to_plane_thresh), b(&window, 0.1);
  a.SetPrefitSource(&prefit, cfg.skeleton_normal_gate_deg);
  b.SetPrefitSource(&prefit, cfg.skeleton_normal_gate_deg);
  b.SetRowsPerPlane(500);
  a.SetNumThreads(2);
  b.SetNumThreads(2);
  // What each gives alone.
  std::vector<PointPlaneRow> want_a, want_b;
  a.BeginScan(frame);
  b.BeginScan(frame);
  a.ComputeRows(T, &want_a);
  b.ComputeRows(T, &want_b);
  ASSERT_GT(want_a.size(), 2500u);
  ASSERT_LT(want_a.size(), frame.points_lidar.size());
  ASSERT_GT(want_b.size(), 700u);  // of the 1000 kept, those off their plane give none
  ASSERT_LT(want_b.size(), 1000u);

  std::vector<PointPlaneRow> got;
  a.BeginScan(frame);
  b.BeginScan(frame);
  const ResidualProvider::TeamWork wa = a.PrepareRows(T), wb = b.PrepareRows(T);
  ASSERT_EQ(wa.points, frame.points_lidar.size());
  ASSERT_EQ(wb.points, 1000u);
#pragma omp parallel num_threads(2)
  {
    a.RowsInTeam();
    b.RowsInTeam();
  }
  a.FinishRows(T, &got);
  const size_t ends_a = got.size();
  b.FinishRows(T, &got);
  ASSERT_EQ(ends_a, want_a.size());
  ASSERT_EQ(got.size(), want_a.size() + want_b.size());
  for (size_t k = 0; k < got.size(); ++k) {
    const PointPlaneRow& w = k < ends_a ? want_a[k] : want_b[k - ends_a];
    ASSERT_TRUE(got[k].point_lidar == w.point_lidar) << k;
    ASSERT_TRUE(got[k].normal_world == w.normal_world) << k;
    ASSERT_EQ(got[k].offset, w.offset) << k;
    ASSERT_EQ(got[k].weight, w.weight) << k;
  }
  EXPECT_EQ(a.last_matches().size(), want_a.size());
}

}  // namespace
}  // namespace ppf
