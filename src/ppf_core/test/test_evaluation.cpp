// ppf evaluation against hand-computed cases (evo's definitions).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "ppf_core/evaluation.hpp"

namespace ppf {
namespace {

Eigen::Isometry3d Pose(double x, double y, double z, double yaw = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// Reference: unit square corners plus its centre. Estimate: same positions with z errors
// +0.1, -0.1, +0.1, -0.1, 0 (zero mean, uncorrelated with x/y, so the optimal alignment is the
// identity), then moved by a rigid G. By hand, APE after SE(3) alignment:
//   errors {0.1, 0.1, 0.1, 0.1, 0}: rmse = sqrt(0.04/5) = 0.0894427191, mean 0.08, median 0.1,
//   std = sqrt(0.008 - 0.0064) = 0.04, min 0, max 0.1.
void HandCase(Trajectory* ref, Trajectory* est, const Eigen::Isometry3d& G) {
  const double xy[5][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}, {0.5, 0.5}};
  const double ez[5] = {0.1, -0.1, 0.1, -0.1, 0.0};
  for (int i = 0; i < 5; ++i) {
    ref->push_back({static_cast<double>(i), Pose(xy[i][0], xy[i][1], 0.0, 0.3 * i)});
    est->push_back({static_cast<double>(i) + 0.004,  // within max_diff 0.01
                    G * Pose(xy[i][0], xy[i][1], ez[i], 0.3 * i)});
  }
}

TEST(Evaluation, ApeHandComputedSe3) {
  Trajectory ref, est;
  HandCase(&ref, &est, Pose(5.0, 2.0, 1.0, 0.5236));
  EvalOptions o;
  o.align = Alignment::kSE3;
  const EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.matched, 5u);
  EXPECT_NEAR(r.stats.rmse, std::sqrt(0.008), 1e-9);
  EXPECT_NEAR(r.stats.mean, 0.08, 1e-9);
  EXPECT_NEAR(r.stats.median, 0.1, 1e-9);
  EXPECT_NEAR(r.stats.std, 0.04, 1e-9);
  EXPECT_NEAR(r.stats.min, 0.0, 1e-9);
  EXPECT_NEAR(r.stats.max, 0.1, 1e-9);
  EXPECT_NEAR(r.stats.sse, 0.04, 1e-9);
  EXPECT_NEAR(r.scale, 1.0, 1e-12);
}

TEST(Evaluation, ApeWithoutAlignmentSeesTheOffset) {
  Trajectory ref, est;
  HandCase(&ref, &est, Pose(0.3, 0.0, 0.4));
  EvalOptions o;
  o.align = Alignment::kNone;
  const EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok);
  // Errors: |(0.3, 0, 0.4 + ez)| = {sqrt(0.09+0.25), sqrt(0.09+0.09), ..., 0.5}.
  const double a = std::sqrt(0.34), b = std::sqrt(0.18), c = 0.5;
  EXPECT_NEAR(r.stats.max, a, 1e-9);
  EXPECT_NEAR(r.stats.min, b, 1e-9);
  EXPECT_NEAR(r.stats.rmse, std::sqrt((2 * 0.34 + 2 * 0.18 + 0.25) / 5), 1e-9);
  EXPECT_NEAR(r.stats.median, c, 1e-9);
}

TEST(Evaluation, Sim3RemovesScale) {
  Trajectory ref, est;
  const double xy[4][2] = {{0, 0}, {2, 0}, {2, 1}, {0, 3}};
  const Eigen::Isometry3d G = Pose(1.0, -2.0, 0.5, 1.0);
  for (int i = 0; i < 4; ++i) {
    ref.push_back({1.0 * i, Pose(xy[i][0], xy[i][1], 0.1 * i)});
    Eigen::Isometry3d T = Pose(xy[i][0], xy[i][1], 0.1 * i);
    T.translation() *= 0.5;  // estimate at half scale
    est.push_back({1.0 * i, G * T});
  }
  EvalOptions o;
  o.align = Alignment::kSim3;
  EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.scale, 2.0, 1e-9);
  EXPECT_NEAR(r.stats.max, 0.0, 1e-9);
  o.align = Alignment::kSE3;
  r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok);
  EXPECT_GT(r.stats.rmse, 0.3);
}

// Reference along x at 0,1,2,3; estimate at 0,1.1,2.1,3.3 (identity rotations).
// delta 1 frame: relative errors {0.1, 0, 0.2}: rmse sqrt(0.05/3), mean 0.1, median 0.1,
// std sqrt(0.05/3 - 0.01), min 0, max 0.2.
TEST(Evaluation, RpeHandComputed) {
  Trajectory ref, est;
  const double xe[4] = {0.0, 1.1, 2.1, 3.3};
  for (int i = 0; i < 4; ++i) {
    ref.push_back({1.0 * i, Pose(1.0 * i, 0, 0)});
    est.push_back({1.0 * i, Pose(xe[i], 0, 0)});
  }
  EvalOptions o;
  o.align = Alignment::kNone;
  o.delta = 1;
  EvalResult r = ComputeRpe(ref, est, o);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.errors.size(), 3u);
  EXPECT_NEAR(r.stats.rmse, std::sqrt(0.05 / 3), 1e-9);
  EXPECT_NEAR(r.stats.mean, 0.1, 1e-9);
  EXPECT_NEAR(r.stats.median, 0.1, 1e-9);
  EXPECT_NEAR(r.stats.std, std::sqrt(0.05 / 3 - 0.01), 1e-9);
  EXPECT_NEAR(r.stats.min, 0.0, 1e-9);
  EXPECT_NEAR(r.stats.max, 0.2, 1e-9);

  o.delta = 2;  // pairs (0, 2) only: |2.1 - 2| = 0.1
  r = ComputeRpe(ref, est, o);
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NEAR(r.errors[0], 0.1, 1e-9);

  // 1 m along the estimate path: anchors at 1 (1.1 m), 2 (1.0 m), 3 (1.2 m): errors {0, 0.2}.
  o.delta = 1.0;
  o.delta_in_meters = true;
  r = ComputeRpe(ref, est, o);
  ASSERT_TRUE(r.ok);
  ASSERT_EQ(r.errors.size(), 2u);
  EXPECT_NEAR(r.errors[0], 0.0, 1e-9);
  EXPECT_NEAR(r.errors[1], 0.2, 1e-9);
}

TEST(Evaluation, RpeIgnoresAConstantHeadingOffset) {
  // Same body-frame motion seen from a frame rotated by 90 degrees: RPE is 0, APE would not be.
  Trajectory ref = {{0, Pose(0, 0, 0)}, {1, Pose(1, 0, 0)}};
  Trajectory est = {{0, Pose(0, 0, 0, M_PI / 2)}, {1, Pose(0, 1, 0, M_PI / 2)}};
  EvalOptions o;
  o.align = Alignment::kNone;
  const EvalResult r = ComputeRpe(ref, est, o);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.errors[0], 0.0, 1e-9);  // relative motions agree in the body frame
}

TEST(Evaluation, AssociationMaxDiffAndOffset) {
  Trajectory ref, est;
  for (int i = 0; i < 10; ++i) {
    ref.push_back({0.1 * i, Pose(i, 0, 0)});
    est.push_back({0.1 * i + 0.02, Pose(i, 0, 0)});
  }
  EXPECT_TRUE(AssociateByStamp(ref, est, 0.01, 0.0).empty());
  EXPECT_EQ(AssociateByStamp(ref, est, 0.03, 0.0).size(), 10u);
  const auto pairs = AssociateByStamp(ref, est, 0.01, -0.02);
  ASSERT_EQ(pairs.size(), 10u);
  for (const auto& [i, j] : pairs) EXPECT_EQ(i, j);
  EvalOptions o;
  EXPECT_FALSE(ComputeApe(ref, est, o).ok);  // nothing matches at 0.01 s
}

TEST(Evaluation, TumAndKittiRoundTrip) {
  Trajectory traj = {{1.5, Pose(1, 2, 3, 0.2)}, {1.6, Pose(-1, 0.5, 2, -1.0)}};
  const std::string tum = ::testing::TempDir() + "/ppf_eval_test.tum";
  const std::string kitti = ::testing::TempDir() + "/ppf_eval_test.kitti";
  ASSERT_TRUE(WriteTum(tum, traj));
  ASSERT_TRUE(WriteKitti(kitti, traj));
  Trajectory a, b;
  std::string err;
  ASSERT_TRUE(ReadTum(tum, &a, &err)) << err;
  ASSERT_TRUE(ReadKitti(kitti, &b, &err)) << err;
  ASSERT_EQ(a.size(), 2u);
  ASSERT_EQ(b.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_NEAR(a[i].stamp_s, traj[i].stamp_s, 1e-9);
    EXPECT_TRUE(a[i].T.isApprox(traj[i].T, 1e-8));
    EXPECT_TRUE(b[i].T.isApprox(traj[i].T, 1e-8));
    EXPECT_EQ(b[i].stamp_s, static_cast<double>(i));
  }
  std::remove(tum.c_str());
  std::remove(kitti.c_str());
}

TEST(Evaluation, MalformedFilesAreErrors) {
  Trajectory t;
  std::string err;
  EXPECT_FALSE(ParseTum("# c\n0 1 2 3 0 0 0 1\n1 2 3\n", &t, &err));
  EXPECT_NE(err.find("line 3"), std::string::npos) << err;
  EXPECT_FALSE(ParseTum("0 1 2 3 0 0 0 0\n", &t, &err));  // zero quaternion
  EXPECT_FALSE(ParseKitti("1 0 0 0 0 1 0 0 0 0 1\n", &t, &err));
  EXPECT_FALSE(ParseTum("0 1 2 x 0 0 0 1\n", &t, &err));
  EXPECT_FALSE(ReadTum("/nonexistent/file.tum", &t, &err));
}

TEST(Evaluation, AlignmentNeedsThreeNonCollinearPoints) {
  Trajectory ref = {{0, Pose(0, 0, 0)}, {1, Pose(1, 0, 0)}, {2, Pose(2, 0, 0)}};
  EvalOptions o;
  const EvalResult r = ComputeApe(ref, ref, o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("alignment"), std::string::npos);
  o.align = Alignment::kNone;
  EXPECT_TRUE(ComputeApe(ref, ref, o).ok);
}

TEST(Evaluation, StatsTableListsEvoRowsInEvoOrder) {
  ErrorStats st = ComputeStats({0.1, 0.2, 0.3});
  const std::string t = FormatStatsTable("APE w.r.t. translation part (m)",
                                         AlignmentDescription(Alignment::kSE3), st);
  EXPECT_NE(t.find("APE w.r.t. translation part (m)\n(with SE(3) Umeyama alignment)\n\n"),
            std::string::npos);
  size_t last = 0;
  for (const char* row : {"max", "mean", "median", "min", "rmse", "sse", "std"}) {
    const size_t at = t.find(std::string(row) + "\t");
    ASSERT_NE(at, std::string::npos) << row;
    EXPECT_GT(at, last);
    last = at;
  }
  EXPECT_NE(t.find("      rmse\t0.216025\n"), std::string::npos) << t;
}

}  // namespace
}  // namespace ppf
