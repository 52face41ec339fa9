#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <tuple>
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

// The algorithm as ransac.hpp states it, with every hypothesis counted in full: samples drawn
// serially in batches of 16, the adaptive count updated after each batch, the strided pre-test
// against the best support at the batch's start, ties keep the earlier hypothesis.
RansacResult PlainRansac(const std::vector<Eigen::Vector3f>& pts, const RansacParams& params,
                         SplitMix64* rng) {
  const size_t n = pts.size();
  const size_t stride = std::clamp<size_t>(n / 256, 1, 8);
  const long m = static_cast<long>((n + stride - 1) / stride);
  const float delta = static_cast<float>(params.delta);
  const auto count = [&](const Eigen::Vector3f& nf, float d, size_t step) {
    long c = 0;
    for (size_t i = 0; i < n; i += step) {
      c += std::abs(nf.x() * pts[i].x() + nf.y() * pts[i].y() + nf.z() * pts[i].z() + d) < delta;
    }
    return c;
  };
  RansacResult r;
  long best = -1;
  Eigen::Vector3f best_n = Eigen::Vector3f::UnitZ();
  float best_d = 0.f;
  int needed = params.max_iterations;
  while (r.iterations < needed && r.degenerate_samples < params.max_degenerate_samples) {
    std::vector<std::pair<Eigen::Vector3f, float>> batch;
    const int want = std::min(16, needed - r.iterations);
    while (static_cast<int>(batch.size()) < want &&
           r.degenerate_samples < params.max_degenerate_samples) {
      const uint32_t i0 = rng->Below(n), i1 = rng->Below(n), i2 = rng->Below(n);
      std::optional<Plane> plane;
      if (i0 != i1 && i1 != i2 && i0 != i2) {
        plane = Plane::FromPoints(pts[i0].cast<double>(), pts[i1].cast<double>(),
                                  pts[i2].cast<double>(), params.min_sample_area);
      }
      if (!plane) {
        ++r.degenerate_samples;
        continue;
      }
      batch.emplace_back(plane->n.cast<float>(), static_cast<float>(plane->d));
    }
    if (batch.empty()) break;
    const long reference = std::max<long>(best, params.min_inliers);
    const bool pretest = stride > 1 && reference * m >= 16 * static_cast<long>(n);
    std::vector<long> counts;
    for (const auto& [nf, d] : batch) {
      const bool rejected =
          pretest && 2 * count(nf, d, stride) * static_cast<long>(n) < reference * m;
      counts.push_back(rejected ? -1 : count(nf, d, 1));
    }
    for (size_t b = 0; b < batch.size(); ++b) {
      ++r.iterations;
      if (counts[b] == -1) ++r.pretest_rejected;
      if (counts[b] > best) {
        best = counts[b];
        std::tie(best_n, best_d) = batch[b];
        needed = RansacIterationsNeeded(static_cast<double>(best) / static_cast<double>(n),
                                        params.confidence, params.max_iterations);
      }
    }
  }
  if (best < 0) return r;
  r.num_inliers = static_cast<int>(best);
  r.plane.n = best_n.cast<double>().normalized();
  r.plane.d = static_cast<double>(best_d);
  r.success = best >= params.min_inliers;
  return r;
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

TEST(PpfRansac, AbandonedCountsPickWhatFullCountsPick) {
  // Full counts add the points outside the pre-test's subset to the subset's count and stop
  // early once a hypothesis cannot beat the best (ransac.cpp); on clouds of 600-9000 points
  // (pre-test strides 2-8, several count blocks), with planes, clutter and different seeds, the
  // result must be exactly that of counting every hypothesis over all points.
  int abandoned = 0;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    std::vector<Eigen::Vector3f> pts;
    std::mt19937 rng(seed);
    const int scale = static_cast<int>(seed);
    test::AddPatch({-20, -20, -1.5}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 40, 40,
                   300 * scale, 0.05, &rng, &pts);
    test::AddPatch({-20, 10, -1.5}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitZ(), 40, 6,
                   150 * scale, 0.05, &rng, &pts);
    test::AddClutter({-20, -20, 0.0}, {20, 20, 5}, 500 * scale * scale / 2 + 100, &rng, &pts);
    RansacParams params;
    params.delta = 0.2;
    params.min_inliers = 80;
    SplitMix64 rng_a(seed * 11), rng_b(seed * 11);
    const RansacResult a = FitPlaneRansac(pts, params, &rng_a);
    const RansacResult b = PlainRansac(pts, params, &rng_b);
    SCOPED_TRACE(testing::Message() << "seed " << seed << ", " << pts.size() << " points");
    EXPECT_EQ(a.success, b.success);
    EXPECT_EQ(a.plane.n, b.plane.n);  // bit-identical
    EXPECT_EQ(a.plane.d, b.plane.d);
    EXPECT_EQ(a.num_inliers, b.num_inliers);
    EXPECT_EQ(a.iterations, b.iterations);
    EXPECT_EQ(a.pretest_rejected, b.pretest_rejected);
    EXPECT_EQ(rng_a.Next(), rng_b.Next());  // the same samples drawn
    abandoned += a.count_abandoned;
  }
  EXPECT_GT(abandoned, 100);  // the shortcut was taken
}

}  // namespace
}  // namespace ppf
