#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/plane_prefitter.hpp"
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

}  // namespace
}  // namespace ppf
