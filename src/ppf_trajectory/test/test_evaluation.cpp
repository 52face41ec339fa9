// ppf evaluation against hand-computed cases (evo's definitions).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "ppf_trajectory/evaluation.hpp"

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

// A rigid motion that only yaws and translates: what the 4-DoF alignment may remove.
Eigen::Isometry3d YawMove(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  G.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  G.translation() = t;
  return G;
}

Eigen::Isometry3d RotX(double angle) {
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  G.linear() = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return G;
}

double Deg(double d) { return d * M_PI / 180.0; }

// A wavy, climbing, non-symmetric path with rolling and pitching orientations.
Trajectory Wiggly(int n) {
  Trajectory ref;
  for (int i = 0; i < n; ++i) {
    const double u = 0.1 * i;
    Eigen::Isometry3d T = Pose(3.0 * u, std::sin(u) + 0.2 * u * u, 0.05 * u, 0.4 * u);
    T.linear() = T.linear() *
                 Eigen::AngleAxisd(0.1 * std::cos(u), Eigen::Vector3d::UnitX()).toRotationMatrix();
    ref.push_back({u, T});
  }
  return ref;
}

TEST(Evaluation, PosYawRecoversAKnownYawAndTranslation) {
  const Trajectory ref = Wiggly(50);
  const Eigen::Isometry3d G = YawMove(2.5, Eigen::Vector3d(10.0, -4.0, 1.5));
  Trajectory est;
  for (const StampedPose& p : ref) est.push_back({p.stamp_s, G * p.T});
  EvalOptions o;
  o.align = Alignment::kPosYaw;
  const EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.matched, 50u);
  EXPECT_LT(r.stats.max, 1e-9);
  EXPECT_TRUE(r.T_ref_est.isApprox(G.inverse(), 1e-9)) << r.T_ref_est.matrix();
  EXPECT_EQ(r.scale, 1.0);
  // Without alignment the same estimate is far off: the check above is not vacuous.
  o.align = Alignment::kNone;
  EXPECT_GT(ComputeApe(ref, est, o).stats.min, 1.0);
}

// Reference: the corners (+-1, +-1, 0) of a square. Estimate: the reference in a world rolled by
// 1 degree about x, then yawed and moved by G. Rolled, a corner (x, y, 0) becomes
// (x, y cos a, y sin a): centred still, and sum(x_e y_r - y_e x_r) = (1 - cos a) sum(x y) = 0
// over the square, so the best yaw undoes G's and nothing more. Every corner then stays off by
// |(0, y (1 - cos a), -y sin a)| = 2 sin(a / 2) with |y| = 1: that is the 4-DoF APE.
TEST(Evaluation, PosYawKeepsARolledWorldAsError) {
  const double xy[4][2] = {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
  const double a = Deg(1.0);
  const Eigen::Isometry3d G = YawMove(-0.8, Eigen::Vector3d(3.0, -2.0, 1.0));
  Trajectory ref, est;
  for (int i = 0; i < 4; ++i) {
    ref.push_back({1.0 * i, Pose(xy[i][0], xy[i][1], 0.0, 0.5 * i)});
    est.push_back({1.0 * i, G * RotX(a) * ref.back().T});
  }
  EvalOptions o;
  o.align = Alignment::kPosYaw;
  const EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok) << r.error;
  const double expected = 2.0 * std::sin(a / 2.0);
  EXPECT_NEAR(r.stats.rmse, expected, 1e-6);
  EXPECT_NEAR(r.stats.min, expected, 1e-6);
  EXPECT_NEAR(r.stats.max, expected, 1e-6);
  EXPECT_TRUE(r.T_ref_est.isApprox(G.inverse(), 1e-9)) << r.T_ref_est.matrix();
  // SE(3) may rotate about x too and hides the roll entirely.
  o.align = Alignment::kSE3;
  const EvalResult se3 = ComputeApe(ref, est, o);
  ASSERT_TRUE(se3.ok) << se3.error;
  EXPECT_LT(se3.stats.max, 1e-9);
  // The roll is also what the tilt measures, whatever the alignment.
  ASSERT_TRUE(r.gravity.ok);
  EXPECT_NEAR(r.gravity.tilt.max, 1.0, 1e-9);
  EXPECT_NEAR(se3.gravity.tilt.max, 1.0, 1e-9);
}

TEST(Evaluation, PosYawNeedsHorizontalExtent) {
  // A vertical line: every yaw fits.
  Trajectory ref = {{0, Pose(0, 0, 0)}, {1, Pose(0, 0, 1)}, {2, Pose(0, 0, 2)}};
  EvalOptions o;
  o.align = Alignment::kPosYaw;
  const EvalResult r = ComputeApe(ref, ref, o);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("alignment"), std::string::npos);
  // A straight horizontal line is enough for yaw (SE(3) would refuse it).
  Trajectory line = {{0, Pose(0, 0, 0)}, {1, Pose(1, 0, 0)}, {2, Pose(2, 0, 0)}};
  Trajectory moved;
  for (const StampedPose& p : line) {
    moved.push_back({p.stamp_s, YawMove(1.0, Eigen::Vector3d(1, 2, 3)) * p.T});
  }
  const EvalResult l = ComputeApe(line, moved, o);
  ASSERT_TRUE(l.ok) << l.error;
  EXPECT_LT(l.stats.max, 1e-9);
}

TEST(Evaluation, TiltOfAWorldRolledByHalfADegree) {
  const Trajectory ref = Wiggly(40);
  const Eigen::Isometry3d roll = RotX(Deg(0.5));
  Trajectory est;
  for (const StampedPose& p : ref) est.push_back({p.stamp_s, roll * p.T});
  const GravityMetrics g = ComputeGravityMetrics(ref, est, EvalOptions());
  ASSERT_TRUE(g.ok);
  ASSERT_EQ(g.tilt_deg.size(), 40u);
  for (double t : g.tilt_deg) EXPECT_NEAR(t, 0.5, 1e-9);
  EXPECT_EQ(g.tilt.count, 40u);
  EXPECT_NEAR(g.tilt.median, 0.5, 1e-9);
  EXPECT_NEAR(g.tilt.max, 0.5, 1e-9);
}

TEST(Evaluation, TiltIgnoresYawAndCountsOnlyPosesAfterTheOffset) {
  const Trajectory ref = Wiggly(40);  // stamps 0, 0.1, ..., 3.9 s
  Trajectory est;
  for (const StampedPose& p : ref) {
    // Yawed and moved everywhere; tilted by 2 degrees about y only in the first second.
    Eigen::Isometry3d T = YawMove(1.2, Eigen::Vector3d(5, 6, 7)) * p.T;
    if (p.stamp_s < 1.0 - 1e-9) {
      T.linear() =
          Eigen::AngleAxisd(Deg(2.0), Eigen::Vector3d::UnitY()).toRotationMatrix() * T.linear();
    }
    est.push_back({p.stamp_s, T});
  }
  EvalOptions o;
  GravityMetrics g = ComputeGravityMetrics(ref, est, o);
  ASSERT_TRUE(g.ok);
  EXPECT_NEAR(g.tilt.max, 2.0, 1e-9);
  EXPECT_NEAR(g.tilt_deg.back(), 0.0, 1e-9);
  o.tilt_after_s = 1.0;
  g = ComputeGravityMetrics(ref, est, o);
  ASSERT_TRUE(g.ok);
  EXPECT_EQ(g.tilt.count, 30u);  // 1.0 s .. 3.9 s
  EXPECT_NEAR(g.tilt.max, 0.0, 1e-9);
  EXPECT_NEAR(g.tilt.median, 0.0, 1e-9);
  o.tilt_after_s = 10.0;  // past the end: no pose to measure, not a tilt of zero
  g = ComputeGravityMetrics(ref, est, o);
  ASSERT_TRUE(g.ok);
  EXPECT_EQ(g.tilt.count, 0u);
}

// A level straight line of length L along y; the estimate pitches its world by `a` about the x
// axis through the first position, and is then yawed and moved. The final height error is
// L sin(a), the largest too; in % of the path 100 sin(a).
TEST(Evaluation, HeightErrorOfATiltedStraightLine) {
  const double L = 120.0, a = Deg(0.5);
  const Eigen::Vector3d p0(4.0, -3.0, 2.0);
  auto pitched_about_p0 = [&](double angle) {
    return Eigen::Translation3d(p0) * RotX(angle) * Eigen::Translation3d(-p0);
  };
  const Eigen::Isometry3d G = YawMove(2.0, Eigen::Vector3d(-7.0, 1.0, 9.0)) * pitched_about_p0(a);
  Trajectory ref, est;
  for (int i = 0; i <= 60; ++i) {
    const Eigen::Isometry3d T = Pose(p0.x(), p0.y() + L * i / 60.0, p0.z(), 0.3);
    ref.push_back({0.5 * i, T});
    est.push_back({0.5 * i + 0.003, G * T});
  }
  EvalOptions o;
  o.align = Alignment::kPosYaw;
  const EvalResult r = ComputeApe(ref, est, o);
  ASSERT_TRUE(r.ok) << r.error;
  const GravityMetrics& g = r.gravity;
  ASSERT_TRUE(g.ok);
  EXPECT_NEAR(g.path_length_m, L, 1e-9);
  EXPECT_NEAR(g.final_dz_m, L * std::sin(a), 1e-9);
  EXPECT_NEAR(g.max_abs_dz_m, L * std::sin(a), 1e-9);
  EXPECT_NEAR(g.FinalDzPercent(), 100.0 * std::sin(a), 1e-9);
  EXPECT_NEAR(g.tilt.max, 0.5, 1e-9);
  // Pitched the other way: the sign follows.
  est.clear();
  const Eigen::Isometry3d H = pitched_about_p0(-a);
  for (const StampedPose& p : ref) est.push_back({p.stamp_s, H * p.T});
  const GravityMetrics down = ComputeGravityMetrics(ref, est, o);
  ASSERT_TRUE(down.ok);
  EXPECT_NEAR(down.final_dz_m, -L * std::sin(a), 1e-9);
  EXPECT_NEAR(down.max_abs_dz_m, L * std::sin(a), 1e-9);
}

TEST(Evaluation, GravityLinesNameTheirNumbers) {
  GravityMetrics g;
  EXPECT_EQ(FormatGravityLines(g, 0.0), "");  // nothing matched: nothing to say
  g.ok = true;
  g.tilt = ComputeStats({0.1, 0.3, 0.2});
  g.final_dz_m = -0.25;
  g.max_abs_dz_m = 0.5;
  g.path_length_m = 100.0;
  const std::string s = FormatGravityLines(g, 10.0);
  EXPECT_NE(s.find("3 poses from 10 s on): median 0.2000, max 0.3000\n"), std::string::npos) << s;
  EXPECT_NE(s.find("final -0.2500 m (-0.2500 % of a 100.0 m path), max |dz| 0.5000 m\n"),
            std::string::npos)
      << s;
  // ppf_eval's callers read the last "rmse" line of its output as the APE: never here.
  EXPECT_EQ(s.find("rmse"), std::string::npos);
  g.tilt = ComputeStats({});
  EXPECT_NE(FormatGravityLines(g, 10.0).find("no pose from 10 s on"), std::string::npos);
}

}  // namespace
}  // namespace ppf
