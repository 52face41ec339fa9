#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "ppf_core/ppf/plane_prefitter.hpp"
#include "ppf_core/ppf/sandwich_layer.hpp"
#include "ppf_core/ppf/skeleton_residual.hpp"
#include "ppf_test_scenes.hpp"

namespace ppf {
namespace {

TEST(PpfSandwich, ClassifiesTheThreeBands) {
  EXPECT_EQ(ClassifySandwich(0.0, 0.1, 4.0), SandwichClass::kStrict);
  EXPECT_EQ(ClassifySandwich(-0.099, 0.1, 4.0), SandwichClass::kStrict);
  EXPECT_EQ(ClassifySandwich(0.1, 0.1, 4.0), SandwichClass::kSemi);  // delta itself is semi
  EXPECT_EQ(ClassifySandwich(-0.39, 0.1, 4.0), SandwichClass::kSemi);
  EXPECT_EQ(ClassifySandwich(0.4, 0.1, 4.0), SandwichClass::kOutlier);
  EXPECT_EQ(ClassifySandwich(-7.0, 0.1, 4.0), SandwichClass::kOutlier);

  const std::vector<Eigen::Vector3f> pts = {
      {0, 0, 0.05f}, {0, 0, -0.2f}, {0, 0, 0.5f}, {0, 0, -0.01f}, {0, 0, 0.3f}};
  SandwichSplit split;
  SplitSandwich(pts, Plane{Eigen::Vector3d::UnitZ(), 0.0}, 0.1, 4.0, &split);
  EXPECT_EQ(split.strict, (std::vector<int>{0, 3}));
  EXPECT_EQ(split.semi, (std::vector<int>{1, 4}));
  EXPECT_EQ(split.outliers, (std::vector<int>{2}));
}

// LabelSandwich's labels and strict list, on a cloud below and one above the size where the
// labelling runs in blocks on a team: every point as the per-point float test labels it (a NaN
// distance an outlier), the strict positions ascending, points exactly on both band edges included.
TEST(PpfSandwich, LabelsEveryPointAsThePointTestInOrder) {
  const Plane plane{Eigen::Vector3d(0.36, -0.48, 0.8), -1.25};
  const double delta = 0.2, semi_factor = 2.0;
  const float nx = 0.36f, ny = -0.48f, nz = 0.8f, d = -1.25f;
  const float strict = 0.2f, semi = 0.4f;
  for (const size_t size : {size_t{10007}, size_t{70001}}) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-3.0f, 3.0f);
    std::vector<Eigen::Vector3f> pts(size);
    for (auto& p : pts) p = Eigen::Vector3f(u(rng), u(rng), u(rng) * 0.2f + 1.5f);
    // On the edges: distances of exactly +-delta and +-semi_factor * delta along the normal
    // from a point of the plane (what the float expression makes of them decides).
    const Eigen::Vector3f on(0.0f, 0.0f, 1.5625f), n(nx, ny, nz);
    pts[3] = on + strict * n;
    pts[4] = on - strict * n;
    pts[5] = on + semi * n;
    pts[6] = on - semi * n;
    pts[size - 1] = Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f);
    std::vector<uint8_t> labels;
    SandwichSplit split;
    LabelSandwich(pts, plane, delta, semi_factor, &labels, &split);
    ASSERT_EQ(labels.size(), size);
    std::vector<int> expected_strict;
    size_t semis = 0;
    for (size_t i = 0; i < size; ++i) {
      const float a = std::abs(nx * pts[i].x() + ny * pts[i].y() + nz * pts[i].z() + d);
      const uint8_t want = a < strict ? 0 : (a < semi ? 1 : 2);
      ASSERT_EQ(labels[i], want) << "point " << i << " of " << size;
      if (want == 0) expected_strict.push_back(static_cast<int>(i));
      semis += want == 1 ? 1 : 0;
    }
    EXPECT_EQ(labels[size - 1], 2);
    EXPECT_EQ(split.strict, expected_strict);
    // The cloud straddles the plane: all three classes occur.
    EXPECT_GT(expected_strict.size(), size / 20);
    EXPECT_GT(semis, size / 20);
  }
}

// Paper Fig. 5: flat ground (already in the window F) and a slope rising from it at 5 degrees,
// seen for the first time. Returns the number of skeleton points of the newly fitted slope plane
// that the nearest-plane search (Eq. 10) matches to the ground plane (false matches).
int CrossPlaneMatches(double semi_band_factor, int* slope_skeleton_points) {
  const double delta = 0.1, eps = 0.2;
  std::mt19937 rng(21);
  std::vector<Eigen::Vector3f> pts;
  // Ground: x in [-30, 0], bigger than the slope so it is fitted first (as the ground would be,
  // being in the window, with incremental fitting).
  test::AddPatch({-30, -10, 0}, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), 30, 20, 4000,
                 0.02, &rng, &pts);
  const size_t num_ground = pts.size();
  const double a = 5.0 * M_PI / 180.0;
  const Eigen::Vector3d up_slope(std::cos(a), 0, std::sin(a));
  test::AddPatch({0, -10, 0}, up_slope, Eigen::Vector3d::UnitY(), 15, 20, 2000, 0.02, &rng, &pts);
  const Plane ground{Eigen::Vector3d::UnitZ(), 0.0};

  PpfConfig cfg;
  cfg.delta = delta;
  cfg.point_to_plane_thresh = eps;
  cfg.semi_band_factor = semi_band_factor;
  cfg.plane_least_inliers = 150;
  cfg.min_remaining_ratio = 0.0;  // let it fit the slope too
  // The patches are not LiDAR-sampled: the ground lies in the sensor's horizontal plane, where a
  // real LiDAR would see it with one beam at most, and the beam-spread test rightly refuses it.
  cfg.min_elevation_spread_deg = 0.0;
  PlanePrefitter prefitter(cfg);
  PrefitResult res;
  prefitter.Fit(pts, {}, &res);
  EXPECT_GE(res.planes.size(), 2u);

  // Which fitted plane is the ground, and which plane each skeleton point belongs to.
  int ground_plane = -1;
  for (size_t i = 0; i < res.planes.size(); ++i) {
    if (test::NormalErrorDeg(res.planes[i].plane, ground) < 1.0 &&
        test::OffsetError(res.planes[i].plane, ground) < 0.05) {
      ground_plane = static_cast<int>(i);
    }
  }
  EXPECT_GE(ground_plane, 0);
  std::vector<int> plane_of(pts.size(), -1);
  for (size_t k = 0; k < res.skeleton_indices.size(); ++k) {
    plane_of[res.skeleton_indices[k]] = res.skeleton_plane[k];
  }
  std::vector<SkeletonMatch> matches;
  ComputeSkeletonMatches(pts, res.skeleton_indices, Eigen::Isometry3d::Identity(), {ground}, eps,
                         &matches);
  int cross = 0;
  *slope_skeleton_points = 0;
  for (size_t k = 0; k < res.skeleton_indices.size(); ++k) {
    *slope_skeleton_points += res.skeleton_plane[k] != ground_plane;
  }
  for (const SkeletonMatch& m : matches) {
    // A skeleton point of another (slope) plane matched to the ground is a false match. Slope
    // points that became ground skeleton points are within delta of the ground by construction.
    if (plane_of[m.point_index] != ground_plane) ++cross;
    // With the layer, no slope point truly far from the ground is matched to it at all.
    if (semi_band_factor > 1.0 && m.point_index >= static_cast<int>(num_ground)) {
      const double true_height = std::max(0.0, double(pts[m.point_index].x())) * std::tan(a);
      EXPECT_LT(true_height, delta + 4 * 0.02);
    }
  }
  return cross;
}

TEST(PpfSandwich, TwoPlanesAtFiveDegreesProduceNoCrossPlaneMatches) {
  int slope_points = 0;
  EXPECT_EQ(CrossPlaneMatches(4.0, &slope_points), 0);
  EXPECT_GT(slope_points, 500);  // the slope itself still yields skeleton points
}

TEST(PpfSandwich, WithoutTheSemiLayerTheSlopeMatchesTheGround) {
  // The same scene with the semi band disabled: the check above would have caught this.
  int slope_points = 0;
  EXPECT_GT(CrossPlaneMatches(1.0, &slope_points), 50);
}

}  // namespace
}  // namespace ppf
