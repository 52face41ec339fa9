#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

PpfConfig TestConfig() {
  PpfConfig cfg;
  cfg.plane_least_inliers = 150;
  cfg.incremental_fitting = true;
  return cfg;
}

// Index of the fitted plane closest to `truth` (by angle, then offset), -1 if none within 5 deg.
int FindPlane(const PrefitResult& r, const Plane& truth) {
  int best = -1;
  double best_cost = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < r.planes.size(); ++i) {
    const double ang = test::NormalErrorDeg(r.planes[i].plane, truth);
    const double cost = ang + 10.0 * test::OffsetError(r.planes[i].plane, truth);
    if (ang < 5.0 && cost < best_cost) {
      best_cost = cost;
      best = static_cast<int>(i);
    }
  }
  return best;
}

TEST(PpfPrefitter, RecoversKnownPlanesFromNoisyScan) {
  // Acceptance: 2 cm noise -> normals within 0.5 degrees, offsets within 2 cm.
  for (unsigned seed : {1u, 2u, 3u}) {
    const test::CornerScene scene = test::MakeCornerScene(0.02, 500, seed);
    PpfConfig cfg = TestConfig();
    cfg.min_remaining_ratio = 0.05;  // the three planes hold ~92% of the points; fit all three
    PlanePrefitter prefitter(cfg);
    PrefitResult r;
    prefitter.Fit(scene.points, {}, &r);
    for (const Plane& truth : scene.planes) {
      const int i = FindPlane(r, truth);
      ASSERT_GE(i, 0) << "seed " << seed;
      EXPECT_LT(test::NormalErrorDeg(r.planes[i].plane, truth), 0.5) << "seed " << seed;
      EXPECT_LT(test::OffsetError(r.planes[i].plane, truth), 0.02) << "seed " << seed;
      EXPECT_FALSE(r.planes[i].from_guess);
    }
  }
}

TEST(PpfPrefitter, PartitionCoversEveryPointOnce) {
  test::CornerScene scene = test::MakeCornerScene(0.03, 300, 4);
  scene.points.push_back(Eigen::Vector3f(std::numeric_limits<float>::quiet_NaN(), 0, 0));
  PlanePrefitter prefitter(TestConfig());
  PrefitResult r;
  prefitter.Fit(scene.points, {}, &r);
  ASSERT_EQ(r.skeleton_indices.size(), r.skeleton_plane.size());
  std::vector<int> all = r.skeleton_indices;
  all.insert(all.end(), r.scattered_indices.begin(), r.scattered_indices.end());
  all.insert(all.end(), r.discarded_indices.begin(), r.discarded_indices.end());
  std::sort(all.begin(), all.end());
  ASSERT_EQ(all.size(), scene.points.size());
  for (size_t i = 0; i < all.size(); ++i) ASSERT_EQ(all[i], static_cast<int>(i));
  // The NaN point is discarded, never a skeleton or map point.
  EXPECT_TRUE(std::binary_search(r.discarded_indices.begin(), r.discarded_indices.end(),
                                 static_cast<int>(scene.points.size() - 1)));
  // Skeleton points of a plane are within delta of it.
  for (size_t k = 0; k < r.skeleton_indices.size(); ++k) {
    const Plane& pl = r.planes[r.skeleton_plane[k]].plane;
    ASSERT_LT(pl.Distance(scene.points[r.skeleton_indices[k]].cast<double>()),
              TestConfig().delta);
  }
  int sum = 0;
  for (const auto& p : r.planes) sum += p.num_inliers;
  EXPECT_EQ(sum, static_cast<int>(r.skeleton_indices.size()));
}

TEST(PpfPrefitter, AccurateGuessAcceptedWrongGuessRejected) {
  const test::CornerScene scene = test::MakeCornerScene(0.02, 500, 5);
  // The ground as the previous scan saw it, moved with a slightly wrong predicted motion
  // (1 cm, 0.2 degrees): must be accepted and refined.
  Plane good = scene.planes[0];
  good.d += 0.01;
  good.n = (Eigen::AngleAxisd(0.2 * M_PI / 180, Eigen::Vector3d::UnitX()) * good.n).normalized();
  // A wall guess moved by a wrong motion (0.5 m off): no support within delta -> rejected.
  Plane wrong = scene.planes[1];
  wrong.d += 0.5;
  // A plane rotated by 10 degrees about the wall's centre line: partial support only.
  Plane tilted = scene.planes[2];
  tilted.n = (Eigen::AngleAxisd(10 * M_PI / 180, Eigen::Vector3d::UnitZ()) * tilted.n);
  tilted.d = -tilted.n.dot(Eigen::Vector3d(-6, -6, 2.5));

  PpfConfig cfg = TestConfig();
  cfg.plane_least_inliers = 400;
  PlanePrefitter prefitter(cfg);
  PrefitResult r;
  prefitter.Fit(scene.points, {{good, 10}, {wrong, 11}, {tilted, 12}}, &r);
  EXPECT_EQ(r.guesses_tried, 3);
  EXPECT_EQ(r.guesses_accepted, 1);
  ASSERT_FALSE(r.planes.empty());
  EXPECT_TRUE(r.planes[0].from_guess);
  EXPECT_EQ(r.planes[0].guess_track_id, 10);
  EXPECT_LT(test::NormalErrorDeg(r.planes[0].plane, scene.planes[0]), 0.5);
  EXPECT_LT(test::OffsetError(r.planes[0].plane, scene.planes[0]), 0.02);
  for (size_t i = 1; i < r.planes.size(); ++i) {
    EXPECT_FALSE(r.planes[i].from_guess);
    EXPECT_EQ(r.planes[i].guess_track_id, -1);
  }
  // Both walls are then found by RANSAC.
  EXPECT_GE(FindPlane(r, scene.planes[1]), 1);
  EXPECT_GE(FindPlane(r, scene.planes[2]), 1);

  // Incremental fitting off: guesses are ignored.
  cfg.incremental_fitting = false;
  PlanePrefitter plain(cfg);
  plain.Fit(scene.points, {{good, 10}}, &r);
  EXPECT_EQ(r.guesses_tried, 0);
}

TEST(PpfPrefitter, DuplicateGuessFailsOnceItsPointsAreGone) {
  const test::CornerScene scene = test::MakeCornerScene(0.02, 500, 6);
  PlanePrefitter prefitter(TestConfig());
  PrefitResult r;
  prefitter.Fit(scene.points, {{scene.planes[0], 1}, {scene.planes[0], 2}}, &r);
  EXPECT_EQ(r.guesses_tried, 2);
  EXPECT_EQ(r.guesses_accepted, 1);
}

TEST(PpfPrefitter, StopRules) {
  const test::CornerScene scene = test::MakeCornerScene(0.02, 500, 7);
  PrefitResult r;
  {
    PpfConfig cfg = TestConfig();
    cfg.max_planes_per_scan = 2;
    cfg.min_remaining_ratio = 0.0;
    PlanePrefitter p(cfg);
    p.Fit(scene.points, {}, &r);
    EXPECT_EQ(r.planes.size(), 2u);
    EXPECT_EQ(r.stop, PrefitStop::kMaxPlanes);
  }
  {
    PpfConfig cfg = TestConfig();
    cfg.min_remaining_ratio = 0.35;  // after ground (6/13) and one wall (3/13), ~31% remain
    PlanePrefitter p(cfg);
    p.Fit(scene.points, {}, &r);
    EXPECT_EQ(r.stop, PrefitStop::kFewRemaining);
    EXPECT_LT(r.scattered_indices.size() + 0.0, 0.35 * scene.points.size());
    EXPECT_EQ(r.planes.size(), 2u);
  }
  {
    PpfConfig cfg = TestConfig();  // default 1/4: the second wall is still fitted
    PlanePrefitter p(cfg);
    p.Fit(scene.points, {}, &r);
    EXPECT_EQ(r.stop, PrefitStop::kFewRemaining);
    EXPECT_EQ(r.planes.size(), 3u);
  }
  {
    PpfConfig cfg = TestConfig();
    cfg.min_remaining_ratio = 0.0;
    PlanePrefitter p(cfg);
    p.Fit(scene.points, {}, &r);
    EXPECT_EQ(r.stop, PrefitStop::kRansacFailed);  // clutter alone holds no plane
    EXPECT_EQ(r.planes.size(), 3u);
  }
}

TEST(PpfPrefitter, DegenerateScansDoNotCrash) {
  PlanePrefitter p(TestConfig());
  PrefitResult r;
  p.Fit({}, {}, &r);
  EXPECT_EQ(r.stop, PrefitStop::kEmptyInput);
  EXPECT_TRUE(r.planes.empty());
  p.Fit({Eigen::Vector3f(1, 1, 1), Eigen::Vector3f(1, 2, 1)}, {}, &r);
  EXPECT_EQ(r.scattered_indices.size(), 2u);
  std::vector<Eigen::Vector3f> line;
  for (int i = 0; i < 1000; ++i) line.emplace_back(0.01f * i, 0.f, 1.f);
  p.Fit(line, {{Plane{Eigen::Vector3d::UnitZ(), -1.0}, 3}}, &r);  // guess contains the line
  EXPECT_TRUE(r.planes.empty());
  EXPECT_EQ(r.scattered_indices.size(), line.size());
  std::vector<Eigen::Vector3f> tiny;
  std::mt19937 g(1);
  test::AddClutter({0, 0, 0}, {1e-5, 1e-5, 1e-5}, 500, &g, &tiny);
  p.Fit(tiny, {}, &r);
  EXPECT_TRUE(r.planes.empty());
  EXPECT_EQ(r.scattered_indices.size(), tiny.size());
}

TEST(PpfPrefitter, DeterministicForTheSameInput) {
  const test::CornerScene scene = test::MakeCornerScene(0.05, 300, 8);
  PlanePrefitter p(TestConfig());
  PrefitResult a, b;
  p.Fit(scene.points, {}, &a);
  p.Fit(scene.points, {}, &b);
  ASSERT_EQ(a.planes.size(), b.planes.size());
  for (size_t i = 0; i < a.planes.size(); ++i) {
    EXPECT_EQ(a.planes[i].plane.Coefficients(), b.planes[i].plane.Coefficients());
  }
  EXPECT_EQ(a.skeleton_indices, b.skeleton_indices);
}

// A spinning multi-beam LiDAR (VLP-16 layout) in a round clearing: flat ground `height` below the
// sensor and a vertical wall (or tree line) all around at `wall_radius`, ray-cast in a world frame
// where the sensor is rolled by `roll_deg`. Points are returned in the LiDAR frame, as the
// prefitter gets them. Level, each beam that reaches the wall returns a horizontal circle:
// coplanar points of one elevation angle.
struct ClearingScan {
  std::vector<Eigen::Vector3f> points;
  Plane ground;  // in the LiDAR frame
};

ClearingScan MakeClearingScan(double roll_deg, double height, double wall_radius, unsigned seed) {
  const Eigen::Matrix3d R_world_lidar =
      Eigen::AngleAxisd(roll_deg * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::mt19937 rng(seed);
  std::normal_distribution<double> range_noise(0.0, 0.01);
  ClearingScan s;
  for (int beam = 0; beam < 16; ++beam) {
    const double el = (-15.0 + 2.0 * beam) * M_PI / 180.0;
    for (int col = 0; col < 720; ++col) {
      const double az = col * 0.5 * M_PI / 180.0;
      const Eigen::Vector3d ray_lidar(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                      std::sin(el));
      const Eigen::Vector3d ray = R_world_lidar * ray_lidar;
      double range = std::numeric_limits<double>::infinity();
      if (ray.z() < -1e-6) range = height / -ray.z();
      const double horizontal = std::hypot(ray.x(), ray.y());
      if (horizontal > 1e-6) range = std::min(range, wall_radius / horizontal);
      if (!(range < 100.0)) continue;
      s.points.push_back(((range + range_noise(rng)) * ray_lidar).cast<float>());
    }
  }
  // Ground z_world = -height: n_world . p_world + height = 0 with p_world = R p_lidar.
  s.ground.n = R_world_lidar.transpose() * Eigen::Vector3d::UnitZ();
  s.ground.d = height;
  return s;
}

TEST(PpfPrefitter, OneBeamCircleOnAWallIsNotAPlane) {
  const ClearingScan scan = MakeClearingScan(0.0, 1.8, 12.0, 7);
  PpfConfig cfg;  // 16-beam defaults
  cfg.min_remaining_ratio = 0.02;
  ASSERT_GT(cfg.min_elevation_spread_deg, 0.0) << "the beam-spread test is on by default";
  cfg.max_band_rms_ratio = 0.0;  // a circle is thin: this is the beam-spread test's case alone

  // Without the test, the beams' circles on the wall become horizontal planes above the ground
  // (the failure this guards against).
  PpfConfig off = cfg;
  off.min_elevation_spread_deg = 0.0;
  PrefitResult r0;
  PlanePrefitter(off).Fit(scan.points, {}, &r0);
  int fake = 0;
  for (const FittedPlane& p : r0.planes) {
    if (test::NormalErrorDeg(p.plane, scan.ground) < 5.0 &&
        test::OffsetError(p.plane, scan.ground) > 0.5) {
      ++fake;
    }
  }
  EXPECT_GT(fake, 0) << "the scene must reproduce the one-beam planes";

  PrefitResult r;
  PlanePrefitter(cfg).Fit(scan.points, {}, &r);
  // The ground, crossed by every downward beam up to the wall, is found ...
  const int g = FindPlane(r, scan.ground);
  ASSERT_GE(g, 0);
  EXPECT_LT(test::OffsetError(r.planes[g].plane, scan.ground), 0.05);
  // ... and nothing else: every other point lies on one beam's circle.
  EXPECT_EQ(r.planes.size(), 1u);
  EXPECT_GT(r.shape_rejected, 0);
  // The rejected circles stay in the scan as scattered points (kNN), not thrown away.
  int wall_scattered = 0;
  for (int i : r.scattered_indices) {
    if (scan.ground.Distance(scan.points[i].cast<double>()) > 0.5) ++wall_scattered;
  }
  EXPECT_GT(wall_scattered, static_cast<int>(scan.points.size()) / 2);
}

TEST(PpfPrefitter, GroundSeenBySeveralBeamsIsAPlaneForATiltedSensor) {
  // The test looks at elevation in the LiDAR frame, where a beam's angle does not depend on the
  // sensor's attitude: a tilted (hand-held) sensor's ground is crossed by many beams and kept.
  for (double roll_deg : {0.0, 20.0, -35.0}) {
    SCOPED_TRACE(roll_deg);
    const ClearingScan scan = MakeClearingScan(roll_deg, 1.8, 40.0, 8);
    PpfConfig cfg;
    PrefitResult r;
    PlanePrefitter(cfg).Fit(scan.points, {}, &r);
    const int g = FindPlane(r, scan.ground);
    ASSERT_GE(g, 0);
    EXPECT_LT(test::OffsetError(r.planes[g].plane, scan.ground), 0.05);
    EXPECT_LT(test::NormalErrorDeg(r.planes[g].plane, scan.ground), 0.5);
  }
}

TEST(PpfPrefitter, SlabThroughScatteredPointsIsNotAPlane) {
  // Ground under a layer of tree crowns (points filling a volume): a horizontal slab through the
  // crowns holds as many points as a wall, but they fill the band evenly.
  std::mt19937 rng(11);
  std::vector<Eigen::Vector3f> points;
  test::AddPatch({-20, -20, -1.8}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 40, 40,
                 3000, 0.02, &rng, &points);
  // Crowns of different heights, so that no face of theirs lines up into a plane.
  for (int i = 0; i < 16; ++i) {
    const double x = -20.0 + 10.0 * (i % 4), y = -20.0 + 10.0 * (i / 4), z = 2.0 + 0.37 * i;
    test::AddClutter({x, y, z}, {x + 10.0, y + 10.0, z + 4.0}, 400, &rng, &points);
  }
  const Plane ground{Eigen::Vector3d::UnitZ(), 1.8};
  PpfConfig cfg;
  cfg.plane_least_inliers = 150;
  ASSERT_GT(cfg.max_band_rms_ratio, 0.0) << "the thickness test is on by default";
  // Skeleton points among the crowns' points (all of them lie above z = 1.5).
  const auto crown_skeleton = [&](const PrefitResult& r) {
    int n = 0;
    for (int i : r.skeleton_indices) n += points[i].z() > 1.5f ? 1 : 0;
    return n;
  };

  PpfConfig off = cfg;
  off.max_band_rms_ratio = 0.0;
  PrefitResult r0;
  PlanePrefitter(off).Fit(points, {}, &r0);
  const int slab_points = crown_skeleton(r0);
  ASSERT_GT(slab_points, 1000) << "the scene must reproduce the slabs";

  PrefitResult r;
  PlanePrefitter(cfg).Fit(points, {}, &r);
  const int g = FindPlane(r, ground);
  ASSERT_GE(g, 0);
  EXPECT_LT(test::OffsetError(r.planes[g].plane, ground), 0.02);
  EXPECT_EQ(r.planes[g].num_inliers, 3000);
  EXPECT_GT(r.shape_rejected, 0);
  // A slab that only grazes the crowns (thinner, tilted) can still pass; the bulk does not.
  EXPECT_LT(crown_skeleton(r), slab_points / 4);
}

TEST(PpfPrefitter, ShapeTestsKeepRealPlanes) {
  // Noisy patches span many degrees of elevation and are thin: the defaults give the same
  // planes as both tests off (the paper's behaviour).
  const test::CornerScene scene = test::MakeCornerScene(0.02, 300, 5);
  PpfConfig on = TestConfig();
  PpfConfig off = TestConfig();
  off.min_elevation_spread_deg = 0.0;
  off.max_band_rms_ratio = 0.0;
  PrefitResult r_on, r_off;
  PlanePrefitter(on).Fit(scene.points, {}, &r_on);
  PlanePrefitter(off).Fit(scene.points, {}, &r_off);
  EXPECT_EQ(r_on.shape_rejected, 0);
  ASSERT_EQ(r_on.planes.size(), r_off.planes.size());
  EXPECT_EQ(r_on.skeleton_indices, r_off.skeleton_indices);
}

}  // namespace
}  // namespace ppf
