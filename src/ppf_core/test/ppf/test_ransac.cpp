#include <random>
#include <vector>

#include <gtest/gtest.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "ppf_core/ppf/ransac.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

std::vector<Eigen::Vector3f> NoisyGroundWithClutter(unsigned seed) {
  std::vector<Eigen::Vector3f> pts;
  std::mt19937 rng(seed);
  test::AddPatch({-20, -20, -1.5}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 40, 40, 2000,
                 0.02, &rng, &pts);
  test::AddClutter({-20, -20, 0.0}, {20, 20, 5}, 2000, &rng, &pts);
  return pts;
}

TEST(PpfRansac, FindsTheDominantPlaneAmongHalfOutliers) {
  const auto pts = NoisyGroundWithClutter(1);
  RansacParams params;
  SplitMix64 rng(42);
  const RansacResult r = FitPlaneRansac(pts, params, &rng);
  ASSERT_TRUE(r.success);
  const Plane truth{Eigen::Vector3d::UnitZ(), 1.5};
  // A 3-point hypothesis is coarse; iPCA refines it. Here: right plane, roughly.
  EXPECT_LT(test::NormalErrorDeg(r.plane, truth), 3.0);
  EXPECT_LT(test::OffsetError(r.plane, truth), 0.1);
  EXPECT_GT(r.num_inliers, 1800);
  EXPECT_LE(r.iterations, 300);
}

TEST(PpfRansac, SameSeedSameResultAnyThreadCount) {
  const auto pts = NoisyGroundWithClutter(2);
  RansacParams params;
  SplitMix64 rng_a(7), rng_b(7);
#ifdef _OPENMP
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
#endif
  const RansacResult a = FitPlaneRansac(pts, params, &rng_a);
#ifdef _OPENMP
  omp_set_num_threads(2);
#endif
  const RansacResult b = FitPlaneRansac(pts, params, &rng_b);
#ifdef _OPENMP
  omp_set_num_threads(saved);
#endif
  ASSERT_TRUE(a.success);
  EXPECT_EQ(a.plane.n, b.plane.n);  // bit-identical
  EXPECT_EQ(a.plane.d, b.plane.d);
  EXPECT_EQ(a.num_inliers, b.num_inliers);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.degenerate_samples, b.degenerate_samples);
}

TEST(PpfRansac, AdaptiveIterationCount) {
  // k = log(0.01) / log(1 - 0.5^3) = 34.5 -> 35
  EXPECT_EQ(RansacIterationsNeeded(0.5, 0.99, 300), 35);
  EXPECT_EQ(RansacIterationsNeeded(1.0, 0.99, 300), 1);
  EXPECT_EQ(RansacIterationsNeeded(0.05, 0.99, 300), 300);  // capped
  EXPECT_EQ(RansacIterationsNeeded(0.0, 0.99, 300), 300);
  EXPECT_EQ(RansacIterationsNeeded(1e-9, 0.99, 300), 300);  // w^3 underflow-safe
  // With a clean plane the adaptive count stops early.
  std::vector<Eigen::Vector3f> pts;
  std::mt19937 rng(5);
  test::AddPatch({0, 0, 0}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 10, 10, 1000, 0.01,
                 &rng, &pts);
  SplitMix64 srng(1);
  const RansacResult r = FitPlaneRansac(pts, RansacParams{}, &srng);
  ASSERT_TRUE(r.success);
  EXPECT_LE(r.iterations, 32);  // first batch (16) already has w ~ 1 -> k = 1
}

TEST(PpfRansac, PretestSkipsWeakHypothesesButKeepsTheDominantPlane) {
  // Ground 25 % of the points, a wall 10 %, the rest clutter: w^3 ~ 1.6 % -> ~290 hypotheses.
  // Once the ground is found, hypotheses through clutter or the wall project to far less than
  // half its support on the subset and are not counted in full.
  std::vector<Eigen::Vector3f> pts;
  std::mt19937 rng(9);
  test::AddPatch({-20, -20, -1.5}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 40, 40, 2000,
                 0.02, &rng, &pts);
  test::AddPatch({-20, 10, -1.5}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(), 40, 6, 800,
                 0.02, &rng, &pts);
  test::AddClutter({-20, -20, 0.0}, {20, 20, 5}, 5200, &rng, &pts);
  RansacParams params;
  SplitMix64 srng(3);
  const RansacResult r = FitPlaneRansac(pts, params, &srng);
  ASSERT_TRUE(r.success);
  const Plane ground{Eigen::Vector3d::UnitZ(), 1.5};
  EXPECT_LT(test::NormalErrorDeg(r.plane, ground), 3.0);
  EXPECT_LT(test::OffsetError(r.plane, ground), 0.1);
  EXPECT_GT(r.num_inliers, 1800);
  EXPECT_GT(r.iterations, 250);
  EXPECT_GT(r.pretest_rejected, 200);
  EXPECT_LT(r.pretest_rejected, r.iterations);
  // The reported support is the full count of the returned plane.
  EXPECT_NEAR(r.num_inliers, CountPlaneInliers(pts, r.plane, params.delta), 2);
}

TEST(PpfRansac, DegenerateInputFailsCleanly) {
  RansacParams params;
  params.min_inliers = 3;
  SplitMix64 rng(1);
  // < 3 points
  EXPECT_FALSE(FitPlaneRansac({}, params, &rng).success);
  EXPECT_FALSE(
      FitPlaneRansac({Eigen::Vector3f(1, 2, 3), Eigen::Vector3f(2, 3, 4)}, params, &rng).success);
  // all collinear: every sample is degenerate; the degenerate cap ends the loop
  std::vector<Eigen::Vector3f> line;
  for (int i = 0; i < 500; ++i) line.emplace_back(0.1f * i, 0.2f * i, -0.05f * i);
  const RansacResult r_line = FitPlaneRansac(line, params, &rng);
  EXPECT_FALSE(r_line.success);
  EXPECT_EQ(r_line.iterations, 0);
  EXPECT_EQ(r_line.degenerate_samples, params.max_degenerate_samples);
  // all coincident
  const std::vector<Eigen::Vector3f> same(100, Eigen::Vector3f(5, 5, 5));
  EXPECT_FALSE(FitPlaneRansac(same, params, &rng).success);
  // tiny but non-degenerate cloud (micrometre scale): area guard rejects it, no NaN plane
  std::vector<Eigen::Vector3f> tiny;
  std::mt19937 g(2);
  test::AddClutter({0, 0, 0}, {1e-6, 1e-6, 1e-6}, 50, &g, &tiny);
  const RansacResult r_tiny = FitPlaneRansac(tiny, params, &rng);
  EXPECT_FALSE(r_tiny.success);
  EXPECT_TRUE(r_tiny.plane.n.allFinite());
  // exactly 3 points: succeeds with min_inliers 3
  const std::vector<Eigen::Vector3f> tri = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const RansacResult r_tri = FitPlaneRansac(tri, params, &rng);
  EXPECT_TRUE(r_tri.success);
  EXPECT_EQ(r_tri.num_inliers, 3);
}

TEST(PpfRansac, FailsBelowLeastInliers) {
  const auto pts = NoisyGroundWithClutter(3);  // 2000 ground points
  RansacParams params;
  params.min_inliers = 2500;
  SplitMix64 rng(9);
  const RansacResult r = FitPlaneRansac(pts, params, &rng);
  EXPECT_FALSE(r.success);
  EXPECT_GT(r.num_inliers, 1800);  // it found the plane, just not big enough
}

}  // namespace
}  // namespace ppf
