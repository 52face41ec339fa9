// Plane patch map (plane_patch_map.hpp): where skeleton planes were, so skeleton residuals are
// anchored to the map rather than to the previous scan.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/lio/residual_provider.hpp"
#include "ppf_core/ppf/plane_patch_map.hpp"
#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf/skeleton_residual.hpp"
#include "ppf_core/ppf/skeleton_window.hpp"

namespace ppf {
namespace {

const Eigen::Vector3d kUp = Eigen::Vector3d::UnitZ();

TEST(PlanePatchMap, ParallelSurfacesInOneCellStaySeparatePatches) {
  // A road at z = 0 and the pavement 15 cm higher, both inside the 2 m cell [0,2)^2.
  PlanePatchMap map;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.05, 1.95);
  for (int i = 0; i < 30; ++i) {
    map.Insert({u(rng), u(rng), 0.3}, kUp);
    map.Insert({u(rng), u(rng), 0.45}, -kUp);  // either normal sign is the same surface
  }
  map.FinishInsert();
  EXPECT_EQ(map.num_cells(), 1u);
  ASSERT_EQ(map.num_patches(), 2u);
  const double min_cos = std::cos(10.0 * M_PI / 180.0);
  const auto* road = map.Find({1.0, 1.0, 0.32}, kUp, min_cos);
  const auto* kerb = map.Find({1.0, 1.0, 0.43}, kUp, min_cos);
  ASSERT_NE(road, nullptr);
  ASSERT_NE(kerb, nullptr);
  EXPECT_NE(road, kerb);
  EXPECT_NEAR(road->plane.Distance({0.5, 0.5, 0.3}), 0.0, 1e-9);
  EXPECT_NEAR(kerb->plane.Distance({0.5, 0.5, 0.45}), 0.0, 1e-9);
  // A wall point in the same cell has no patch of its orientation.
  EXPECT_EQ(map.Find({1.0, 1.0, 0.3}, Eigen::Vector3d::UnitX(), min_cos), nullptr);
  // Nor does a neighbouring cell.
  EXPECT_EQ(map.Find({3.0, 1.0, 0.3}, kUp, min_cos), nullptr);
}

TEST(PlanePatchMap, FirstObservationsAnchorThePatch) {
  PlanePatchMapOptions options;
  options.max_points = 20;
  options.min_points = 5;
  PlanePatchMap map(options);
  const double min_cos = std::cos(10.0 * M_PI / 180.0);
  for (int i = 0; i < 4; ++i) map.Insert({0.2 + 0.4 * i, 0.5 + 0.2 * i, 1.0}, kUp);
  map.FinishInsert();
  EXPECT_EQ(map.Find({1.0, 1.0, 1.0}, kUp, min_cos), nullptr) << "fewer than min_points";
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.05, 1.95);
  for (int i = 0; i < 16; ++i) map.Insert({u(rng), u(rng), 1.0}, kUp);
  map.FinishInsert();
  // Later observations 5 cm higher (a drifted pose) do not move the frozen patch.
  for (int i = 0; i < 100; ++i) map.Insert({u(rng), u(rng), 1.05}, kUp);
  map.FinishInsert();
  const auto* patch = map.Find({1.0, 1.0, 1.0}, kUp, min_cos);
  ASSERT_NE(patch, nullptr);
  EXPECT_DOUBLE_EQ(patch->moments.count, 20.0);
  EXPECT_NEAR(patch->plane.Distance({1.0, 1.0, 1.0}), 0.0, 1e-6);
  EXPECT_NEAR(std::abs(patch->plane.n.z()), 1.0, 1e-6);
}

TEST(PlanePatchMap, ANormalComesFromThePatchsOwnPointsNeverFromTheInsertingPlane) {
  // Ground rising 3 % along x, seen first as one scan line across the cell (far away), by a scan
  // whose large ground plane is level: that plane's normal is the scan-wide tangent, 1.7 degrees
  // off here, and a patch carrying it would pass the error on to every later scan.
  const double slope = 0.03;
  const Eigen::Vector3d true_normal = Eigen::Vector3d(-slope, 0.0, 1.0).normalized();
  const auto ground = [&](double x, double y) { return Eigen::Vector3d(x, y, slope * x); };
  PlanePatchMap map;
  const double min_cos = std::cos(10.0 * M_PI / 180.0);
  for (int i = 0; i < 30; ++i) map.Insert(ground(1.0, 0.05 + 0.063 * i), kUp);  // one ring
  map.FinishInsert();
  EXPECT_EQ(map.num_patches(), 1u);
  EXPECT_EQ(map.Find(ground(1.0, 1.0), kUp, min_cos), nullptr) << "a line fixes no normal";
  for (int i = 0; i < 15; ++i) map.Insert(ground(0.3, 0.1 + 0.12 * i), kUp);  // a second ring
  map.FinishInsert();
  const auto* patch = map.Find(ground(1.0, 1.0), kUp, min_cos);
  ASSERT_NE(patch, nullptr);
  EXPECT_GT(std::abs(patch->plane.n.dot(true_normal)), std::cos(0.01 * M_PI / 180.0));
  EXPECT_NEAR(patch->plane.Distance(ground(1.9, 0.2)), 0.0, 1e-9);
}

TEST(PlanePatchMap, BoundedAroundTheSensorAndInCells) {
  PlanePatchMapOptions options;
  options.max_cells = 100;
  PlanePatchMap map(options);
  for (int i = 0; i < 1000; ++i) {
    map.Insert({2.0 * i + 1.0, 1.0, 0.0}, kUp);
    map.FinishInsert();
    EXPECT_LE(map.num_cells(), 100u);
    EXPECT_EQ(map.num_patches(), map.num_cells());  // one surface per cell here
  }
  // The newest cells survive the count bound.
  map.RemoveFarFrom({1999.0, 1.0, 0.0}, 50.0);
  EXPECT_GT(map.num_cells(), 20u);
  EXPECT_LE(map.num_cells(), 26u);
  EXPECT_EQ(map.num_patches(), map.num_cells());
  map.Clear();
  EXPECT_EQ(map.num_patches(), 0u);
  EXPECT_EQ(map.num_cells(), 0u);
}

// Insert keeps the last cell it looked up (a plane's points come several to a cell): a copy of
// the map, a cell dropped by the bounds, and a cleared map must each take a fresh lookup.
TEST(PlanePatchMap, AHintedInsertFeedsTheSameCellsAsAPlainOne) {
  PlanePatchMapOptions options;
  options.min_points = 3;
  options.min_spread_ratio = 0.0;
  const double min_cos = std::cos(10.0 * M_PI / 180.0);
  const auto points_at = [&](const PlanePatchMap& m, const Eigen::Vector3d& p) {
    const PlanePatchMap::Patch* patch = m.Find(p, kUp, min_cos);
    return patch == nullptr ? 0.0 : patch->moments.count;
  };
  // Runs of points in one 2 m cell, then back and forth between cells (0,0), (1,0) and (0,1),
  // and a second surface in the first cell.
  std::vector<Eigen::Vector3d> scan;
  for (int i = 0; i < 5; ++i) scan.emplace_back(0.2 + 0.3 * i, 0.3 + 0.25 * (i % 3), 0.0);
  for (int i = 0; i < 12; ++i) {
    scan.emplace_back(i % 3 == 1 ? 2.5 + 0.1 * i : 0.4 + 0.1 * i,
                      (i % 3 == 2 ? 2.6 : 0.7) + 0.2 * (i % 2), 0.0);
  }
  for (int i = 0; i < 4; ++i) scan.emplace_back(0.3 + 0.4 * i, 0.5 + 0.3 * (i % 2), 1.0);
  const std::vector<Eigen::Vector3d> probes = {
      {1.0, 1.0, 0.0}, {3.0, 1.0, 0.0}, {1.0, 3.0, 0.0}, {1.0, 1.0, 1.0}};
  PlanePatchMap plain(options), hinted(options);
  for (int round = 0; round < 2; ++round) {
    PlanePatchMap::InsertHint hint;  // one scan's
    for (const Eigen::Vector3d& p : scan) {
      plain.Insert(p, kUp);
      hinted.Insert(p, kUp, &hint);
    }
    plain.FinishInsert();
    hinted.FinishInsert();
    EXPECT_EQ(hinted.num_cells(), plain.num_cells());
    EXPECT_EQ(hinted.num_patches(), plain.num_patches());
    for (const Eigen::Vector3d& q : probes) {
      EXPECT_EQ(points_at(hinted, q), points_at(plain, q)) << q.transpose();
    }
    // Cell (0,0) has the first run's 5 on the ground and the second run's 4 with i % 3 == 0.
    EXPECT_EQ(points_at(hinted, probes[0]), 5.0 + 4.0);
    EXPECT_EQ(points_at(hinted, probes[1]), 4.0);
    EXPECT_EQ(points_at(hinted, probes[2]), 4.0);
    EXPECT_EQ(points_at(hinted, probes[3]), 4.0);
    // The cells dropped between scans: the next scan's hint starts afresh on new cells.
    plain.RemoveFarFrom({100.0, 0.0, 0.0}, 10.0);
    hinted.RemoveFarFrom({100.0, 0.0, 0.0}, 10.0);
    ASSERT_EQ(hinted.num_cells(), 0u);
  }
}

TEST(PlanePatchMap, SkeletonResidualsUseThePatchOfTheirCellNotTheWindow) {
  // The window holds last scan's ground fit z = 0.2 (tilted world, drifted pose); the patch map
  // remembers the ground at z = 0. The skeleton point at z = 0.02 must be matched to the patch.
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  FittedPlane ground;
  ground.plane = Plane{kUp, -0.2};
  ground.num_inliers = 500;
  ground.centroid = Eigen::Vector3d(0, 0, 0.2);
  window.Update({ground}, Eigen::Isometry3d::Identity());
  PlanePatchMap patches;
  for (double x = 0.1; x < 2.0; x += 0.3)
    for (double y = 0.1; y < 2.0; y += 0.3) patches.Insert({x, y, 0.0}, kUp);
  patches.FinishInsert();

  ScanFrame frame;
  frame.points_lidar = {Eigen::Vector3f(1.0f, 1.0f, 0.02f), Eigen::Vector3f(5.0f, 5.0f, 0.1f)};
  frame.labels = {PointLabel::kSkeleton, PointLabel::kSkeleton};
  PrefitResult prefit;
  prefit.planes = {ground};
  prefit.skeleton_indices = {0, 1};
  prefit.skeleton_plane = {0, 0};

  for (const bool fallback : {false, true}) {
    SkeletonResidualProvider provider(&window, 0.2);
    provider.SetPrefitSource(&prefit, 10.0);
    provider.SetPatchMap(&patches, fallback);
    provider.BeginScan(frame);
    std::vector<PointPlaneRow> rows;
    provider.ComputeRows(Eigen::Isometry3d::Identity(), &rows);
    const auto& m = provider.last_matches();
    ASSERT_EQ(m.size(), fallback ? 2u : 1u);
    EXPECT_EQ(m[0].point_index, 0);
    EXPECT_EQ(m[0].plane_index, -1) << "matched to a patch";
    EXPECT_NEAR(m[0].signed_distance, 0.02, 1e-6);
    EXPECT_NEAR(rows[0].offset, 0.0, 1e-9);
    if (fallback) {  // the point outside every patch cell: the window plane, as in Eq. 10
      EXPECT_EQ(m[1].point_index, 1);
      EXPECT_EQ(m[1].plane_index, 0);
      EXPECT_NEAR(std::abs(m[1].signed_distance), 0.1, 1e-6);  // 10 cm below the window plane
    }
  }
}

TEST(PlanePatchMap, SkeletonRowsKeepTheirPatchWithinTheKeepDistance) {
  // Two neighbouring cells whose ground patches differ by 3 cm (x < 2 m: z = 0; x >= 2 m: z =
  // 0.03). A skeleton point 1 cm before the cell border keeps the patch it was matched to while
  // a later iteration moves it by less than the keep distance (as the kNN rows keep their
  // neighbours), looks up again beyond it, and starts afresh with the next scan.
  PpfConfig cfg;
  SkeletonWindow window(cfg);
  PlanePatchMap patches;
  for (double x = 0.1; x < 2.0; x += 0.3)
    for (double y = 0.1; y < 2.0; y += 0.3) {
      patches.Insert({x, y, 0.0}, kUp);
      patches.Insert({x + 2.0, y, 0.03}, kUp);
    }
  patches.FinishInsert();
  ASSERT_EQ(patches.num_patches(), 2u);
  FittedPlane ground;
  ground.plane = Plane{kUp, 0.0};
  ground.num_inliers = 500;
  ScanFrame frame;
  frame.points_lidar = {Eigen::Vector3f(1.99f, 1.0f, 0.01f)};
  frame.labels = {PointLabel::kSkeleton};
  PrefitResult prefit;
  prefit.planes = {ground};
  prefit.skeleton_indices = {0};
  prefit.skeleton_plane = {0};
  // The height of the plane the point's row uses (the patch normal's sign is the PCA's).
  auto height_at = [&](SkeletonResidualProvider* provider, double dx) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = dx;
    std::vector<PointPlaneRow> rows;
    provider->ComputeRows(T, &rows);
    EXPECT_EQ(rows.size(), 1u);
    return rows.empty() ? 1.0 : -rows[0].offset / rows[0].normal_world.z();
  };
  for (const double keep : {0.0, 0.05}) {
    SkeletonResidualProvider provider(&window, 0.2);
    provider.SetPrefitSource(&prefit, 10.0);
    provider.SetPatchMap(&patches, false);
    provider.SetKeepDistance(keep);
    provider.BeginScan(frame);
    EXPECT_NEAR(height_at(&provider, 0.0), 0.0, 1e-9);  // cell x < 2: z = 0
    // 2 cm on, across the border: the kept patch, or with keep 0 the new cell's.
    EXPECT_NEAR(height_at(&provider, 0.02), keep > 0.0 ? 0.0 : 0.03, 1e-9) << "keep " << keep;
    EXPECT_NEAR(height_at(&provider, 0.3), 0.03, 1e-9);  // beyond the keep distance
    EXPECT_NEAR(height_at(&provider, 0.0), 0.0, 1e-9);   // ... and back: looked up again
    provider.BeginScan(frame);  // a new scan keeps nothing from the last one
    EXPECT_NEAR(height_at(&provider, 0.02), 0.03, 1e-9);
  }
}

}  // namespace
}  // namespace ppf
