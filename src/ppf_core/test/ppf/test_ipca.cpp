#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "ppf_core/ppf/ipca.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

TEST(PpfIpca, OscillationDetector) {
  EXPECT_FALSE(IpcaCountsOscillate({}));
  EXPECT_FALSE(IpcaCountsOscillate({5, 6, 5}));
  EXPECT_TRUE(IpcaCountsOscillate({5, 6, 5, 6}));
  EXPECT_TRUE(IpcaCountsOscillate({1, 9, 5, 6, 5, 6}));
  EXPECT_FALSE(IpcaCountsOscillate({5, 5, 5, 5}));  // converged, not oscillating
  EXPECT_FALSE(IpcaCountsOscillate({4, 5, 6, 7}));
}

// Noisy ground (5 cm) with a low ramp rising from it and junk in the semi band: a non-strict,
// cluttered plane. Both fits start from the same coarse 3-point RANSAC hypothesis. The single
// least-squares fit uses that hypothesis' strict inliers once, so it inherits the tilt (the band
// cuts the noisy slab obliquely); iPCA re-selects and re-votes until the inlier set is stable.
TEST(PpfIpca, BeatsSingleLeastSquaresUnderNoiseWithSemiInliers) {
  const Plane truth{Eigen::Vector3d::UnitZ(), 0.0};
  const double delta = 0.1;
  double sum_ipca = 0.0, sum_ls = 0.0;
  for (unsigned seed = 0; seed < 5; ++seed) {
    std::mt19937 rng(100 + seed);
    std::vector<Eigen::Vector3f> pts;
    test::AddPatch({-10, -10, 0}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 20, 20, 3000,
                   0.05, &rng, &pts);
    const double slope = 5.0 * M_PI / 180.0;
    test::AddPatch({10, -10, 0}, Eigen::Vector3d(std::cos(slope), 0, std::sin(slope)),
                   Eigen::Vector3d::UnitY(), 10, 20, 1000, 0.05, &rng, &pts);
    test::AddClutter({-10, -10, 0.1}, {10, 10, 0.4}, 500, &rng, &pts);
    // A typical 3-point hypothesis on a 5 cm-noise plane: 1.5 degrees off, 3 cm high.
    const double tilt = 1.5 * M_PI / 180.0;
    const Plane initial{Eigen::Vector3d(std::sin(tilt), 0, std::cos(tilt)), -0.03};

    std::vector<Eigen::Vector3f> inliers;
    for (const auto& p : pts) {
      if (initial.Distance(p.cast<double>()) < delta) inliers.push_back(p);
    }
    const auto ls = FitPlaneLeastSquares(inliers);
    ASSERT_TRUE(ls.has_value());
    const IpcaResult r = RefinePlaneIpca(pts, initial, delta, 3, 150);
    ASSERT_TRUE(r.success);
    EXPECT_FALSE(r.oscillated);
    EXPECT_GT(r.plane.n.dot(initial.n), 0.0);  // orientation kept
    const double err_ipca = test::NormalErrorDeg(r.plane, truth);
    const double err_ls = test::NormalErrorDeg(*ls, truth);
    EXPECT_LT(err_ipca, err_ls) << "seed " << seed;
    EXPECT_LT(err_ipca, 0.5) << "seed " << seed;
    EXPECT_LT(test::OffsetError(r.plane, truth), 0.02) << "seed " << seed;
    sum_ipca += err_ipca;
    sum_ls += err_ls;
  }
  // On average clearly better, not just marginally.
  EXPECT_LT(sum_ipca, 0.5 * sum_ls);
  RecordProperty("mean_err_ipca_deg", std::to_string(sum_ipca / 5));
  RecordProperty("mean_err_single_ls_deg", std::to_string(sum_ls / 5));
}

TEST(PpfIpca, StopsWhenInlierCountStopsChanging) {
  std::mt19937 rng(12);
  std::vector<Eigen::Vector3f> pts;
  test::AddPatch({0, 0, 2}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 10, 10, 1000, 0.005,
                 &rng, &pts);
  const Plane exact{Eigen::Vector3d::UnitZ(), -2.0};
  const IpcaResult r = RefinePlaneIpca(pts, exact, 0.1, 5, 100);
  ASSERT_TRUE(r.success);
  EXPECT_EQ(r.iterations, 1);  // every point is already an inlier: one solve confirms it
  EXPECT_EQ(r.num_inliers, 1000);
  ASSERT_EQ(r.inlier_counts.size(), 2u);
}

// With a bound on the points' reach, passes after a full one visit only the points near its
// plane while the plane stays close: the refinement must be the one over all points, bit for bit,
// for starts that converge within the kept band (a guess) and for starts whose first solve moves
// the plane far beyond it (a coarse 3-point hypothesis, a plane 0.5 m off).
TEST(PpfIpca, PassesOverThePointsNearTheLastPlaneGiveTheFullResult) {
  const test::CornerScene scene = test::MakeCornerScene(0.03, 400, 31);
  const std::vector<Eigen::Vector3f>& pts = scene.points;
  float max_norm2 = 0.0f;
  for (const auto& p : pts) max_norm2 = std::max(max_norm2, p.squaredNorm());
  const double max_norm = std::sqrt(static_cast<double>(max_norm2)) * (1.0 + 1e-5);
  int starts = 0, moved_far = 0;
  for (const Plane& truth : scene.planes) {
    for (const double tilt_deg : {0.0, 0.05, 0.3, 2.0, 6.0}) {
      for (const double offset : {0.0, 0.03, 0.5}) {
        const double a = tilt_deg * M_PI / 180.0;
        // Tilted about an axis perpendicular to the normal.
        const Eigen::Vector3d axis = truth.n.unitOrthogonal();
        const Eigen::Vector3d n = Eigen::AngleAxisd(a, axis) * truth.n;
        const Plane initial{n, truth.d + offset};
        const IpcaResult full = RefinePlaneIpca(pts, initial, 0.2, 5, 50);
        const IpcaResult near = RefinePlaneIpca(pts, initial, 0.2, 5, 50, max_norm);
        ++starts;
        moved_far +=
            (full.plane.n - initial.n).norm() * max_norm + std::abs(full.plane.d - initial.d) > 0.4
                ? 1
                : 0;
        EXPECT_EQ(near.success, full.success);
        EXPECT_EQ(near.oscillated, full.oscillated);
        EXPECT_EQ(near.iterations, full.iterations);
        EXPECT_EQ(near.num_inliers, full.num_inliers);
        EXPECT_EQ(near.inlier_counts, full.inlier_counts);
        EXPECT_EQ(near.plane.n, full.plane.n) << tilt_deg << " deg, " << offset << " m";
        EXPECT_EQ(near.plane.d, full.plane.d) << tilt_deg << " deg, " << offset << " m";
      }
    }
  }
  // Both kinds of start occur: some refinements leave the kept band, some stay in it.
  EXPECT_GT(moved_far, 0);
  EXPECT_LT(moved_far, starts);
}

TEST(PpfIpca, FailsWithoutSupportOrOnLines) {
  std::mt19937 rng(13);
  std::vector<Eigen::Vector3f> pts;
  test::AddPatch({0, 0, 0}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 10, 10, 100, 0.01,
                 &rng, &pts);
  const Plane far{Eigen::Vector3d::UnitZ(), -5.0};
  EXPECT_FALSE(RefinePlaneIpca(pts, far, 0.1, 3, 10).success);
  EXPECT_FALSE(RefinePlaneIpca(pts, Plane{Eigen::Vector3d::UnitZ(), 0.0}, 0.1, 3, 150).success);
  std::vector<Eigen::Vector3f> line;
  for (int i = 0; i < 200; ++i) line.emplace_back(0.05f * i, 0.f, 0.f);
  EXPECT_FALSE(RefinePlaneIpca(line, Plane{Eigen::Vector3d::UnitZ(), 0.0}, 0.1, 3, 10).success);
  EXPECT_FALSE(RefinePlaneIpca({}, Plane{}, 0.1, 3, 3).success);
  EXPECT_FALSE(FitPlaneLeastSquares(line).has_value());
}

}  // namespace
}  // namespace ppf
