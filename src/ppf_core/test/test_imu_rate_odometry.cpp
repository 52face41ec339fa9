// IMU-rate odometry: a posterior propagated with each later IMU sample, against an analytic
// trajectory with exact IMU (synthetic.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include <Eigen/Eigenvalues>

#include "ppf_core/imu_rate_odometry.hpp"
#include "ppf_core/lio/so3.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

constexpr double kRate = 200.0;
constexpr double kT0 = 2.0;  // the scan end the posterior belongs to

// Moving at kT0 (the wiggle starts from rest at 0).
const test::PoseFn kTruth = test::WiggleTrajectory(0.0);

Eigen::Vector3d TrueVelocity(double t) {
  return (kTruth(t + 1e-4).translation() - kTruth(t - 1e-4).translation()) / 2e-4;
}

// What the filter would report at kT0 with the true state: the map frame tilted from the world by
// `R_world_map` (gravity along the map's estimate of down), biases as given.
ScanResult ExactResult(const Eigen::Matrix3d& R_world_map, const Eigen::Vector3d& bg,
                       const Eigen::Vector3d& ba) {
  ScanResult r;
  r.stamp_s = kT0;
  r.status = Status::kOk;
  r.pose_valid = true;
  r.T_world_imu = kTruth(kT0);
  r.T_world_map = Eigen::Isometry3d::Identity();
  r.T_world_map.linear() = R_world_map;
  r.velocity_world = TrueVelocity(kT0);
  r.gyro_bias = bg;
  r.acc_bias = ba;
  r.gravity_map = R_world_map.transpose() * test::kGravity;
  r.covariance = StateCov::Identity() * 1e-6;
  return r;
}

// Sample k of the 200 Hz stream (stamp k / kRate), with biases added and scaled by 1/acc_unit.
ImuSample Sample(int k, const Eigen::Vector3d& bg, const Eigen::Vector3d& ba,
                 double acc_unit = 1.0) {
  ImuSample s = test::ImuFromPose(kTruth, k / kRate);
  s.angular_velocity += bg;
  s.linear_acceleration = (s.linear_acceleration + ba) / acc_unit;
  return s;
}

double RotationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return SO3Log(a.linear().transpose() * b.linear()).norm();
}

// From the exact state, one second of samples lands on the truth at every sample (midpoint
// integration of exact IMU), the twist is the sample's bias-corrected rate and the world
// velocity, and the covariance grows with every sample.
TEST(ImuRateOdometry, FromAnExactStateFollowsTheTruthAndTheCovarianceGrows) {
  ImuRateOdometry::Options o;
  o.acc_scale = 1.0;
  ImuRateOdometry odo(o);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const int k0 = static_cast<int>(kT0 * kRate);
  // Before any posterior: kept, nothing to output.
  for (int k = k0 - 100; k <= k0; ++k) EXPECT_FALSE(odo.AddImu(Sample(k, zero, zero)));
  ASSERT_TRUE(odo.Reset(ExactResult(Eigen::Matrix3d::Identity(), zero, zero)));
  double worst_pos = 0, worst_rot = 0, worst_vel = 0;
  double prev_pos_var = 3e-6, prev_rot_var = 3e-6;
  for (int k = k0 + 1; k <= k0 + 200; ++k) {
    const ImuSample s = Sample(k, zero, zero);
    const auto out = odo.AddImu(s);
    ASSERT_TRUE(out) << k;
    EXPECT_EQ(out->stamp_s, s.stamp_s);
    EXPECT_TRUE(out->angular_velocity.isApprox(s.angular_velocity));
    worst_pos = std::max(worst_pos, (out->T_world_imu.translation() -
                                     kTruth(s.stamp_s).translation()).norm());
    worst_rot = std::max(worst_rot, RotationError(out->T_world_imu, kTruth(s.stamp_s)));
    worst_vel = std::max(worst_vel, (out->velocity_world - TrueVelocity(s.stamp_s)).norm());
    const double pos_var = out->covariance.block<3, 3>(kPos, kPos).trace();
    const double rot_var = out->covariance.block<3, 3>(kRot, kRot).trace();
    EXPECT_GT(pos_var, prev_pos_var) << k;
    EXPECT_GT(rot_var, prev_rot_var) << k;
    prev_pos_var = pos_var;
    prev_rot_var = rot_var;
    EXPECT_TRUE(out->covariance.isApprox(out->covariance.transpose()));
  }
  std::printf("1 s from the exact state: position %.2e m, rotation %.2e rad, velocity %.2e m/s\n",
              worst_pos, worst_rot, worst_vel);
  EXPECT_LT(worst_pos, 1e-5);
  EXPECT_LT(worst_rot, 1e-6);
  EXPECT_LT(worst_vel, 2e-5);
  // One second of the filter's process noise: the position variance at least the acceleration
  // noise integrated twice (sigma^2 t^3 / 3 per axis), far above the 1e-6 it started with.
  const ImuNoise n;
  EXPECT_GT(prev_pos_var, 3e-6 + 3 * n.acc * n.acc / 3.0 * 0.9);
  EXPECT_EQ(odo.counters().late, 0u);
}

// The posterior comes after samples past its stamp: it is re-propagated through them, and the
// outputs after that equal those of a posterior that came in time. Biases are removed, and a
// driver reporting in g is detected. The map tilted against the world: gravity is carried into
// the world with T_world_map and the poses stay the world's.
TEST(ImuRateOdometry, ALatePosteriorIsRepropagatedThroughTheKeptSamples) {
  const Eigen::Vector3d bg(0.01, -0.02, 0.005), ba(0.1, -0.05, 0.2);
  const Eigen::Matrix3d R_world_map =
      Eigen::AngleAxisd(0.03, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  const ScanResult r = ExactResult(R_world_map, bg, ba);
  const int k0 = static_cast<int>(kT0 * kRate);
  const double g_unit = 9.80665;
  ImuRateOdometry in_time, late;  // acc_scale detected
  for (int k = k0 - 100; k <= k0; ++k) {
    in_time.AddImu(Sample(k, bg, ba, g_unit));
    late.AddImu(Sample(k, bg, ba, g_unit));
  }
  ASSERT_TRUE(in_time.Reset(r));
  // 40 samples (0.2 s) before the late one's posterior arrives: only in_time outputs them.
  for (int k = k0 + 1; k <= k0 + 40; ++k) {
    EXPECT_TRUE(in_time.AddImu(Sample(k, bg, ba, g_unit)));
    EXPECT_FALSE(late.AddImu(Sample(k, bg, ba, g_unit)));
  }
  ASSERT_TRUE(late.Reset(r));
  EXPECT_EQ(late.acc_scale(), g_unit);
  for (int k = k0 + 41; k <= k0 + 200; ++k) {
    const ImuSample s = Sample(k, bg, ba, g_unit);
    const auto a = in_time.AddImu(s), b = late.AddImu(s);
    ASSERT_TRUE(a && b) << k;
    EXPECT_LT((a->T_world_imu.translation() - b->T_world_imu.translation()).norm(), 1e-9) << k;
    EXPECT_LT((a->covariance - b->covariance).norm(), 1e-12) << k;
    EXPECT_LT((b->T_world_imu.translation() - kTruth(s.stamp_s).translation()).norm(), 1e-4) << k;
    EXPECT_LT(RotationError(b->T_world_imu, kTruth(s.stamp_s)), 1e-6) << k;
    EXPECT_TRUE(b->angular_velocity.isApprox(s.angular_velocity - bg)) << k;
  }
}

// A later duplicate or reordered sample is dropped; a gap ends the propagation until the next
// posterior; a result registered without the IMU starts none.
TEST(ImuRateOdometry, GapsLateSamplesAndLidarOnlyResultsStopTheOutput) {
  ImuRateOdometry::Options o;
  o.acc_scale = 1.0;
  ImuRateOdometry odo(o);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  const int k0 = static_cast<int>(kT0 * kRate);
  for (int k = k0 - 10; k <= k0; ++k) odo.AddImu(Sample(k, zero, zero));
  ScanResult lidar_only = ExactResult(Eigen::Matrix3d::Identity(), zero, zero);
  lidar_only.lidar_only = true;
  EXPECT_FALSE(odo.Reset(lidar_only));
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 1, zero, zero)));
  ASSERT_TRUE(odo.Reset(ExactResult(Eigen::Matrix3d::Identity(), zero, zero)));
  EXPECT_TRUE(odo.AddImu(Sample(k0 + 2, zero, zero)));
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 2, zero, zero)));
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 1, zero, zero)));
  EXPECT_EQ(odo.counters().late, 2u);
  EXPECT_TRUE(odo.AddImu(Sample(k0 + 3, zero, zero)));
  // 0.2 s without samples (default max_gap_s 0.1).
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 43, zero, zero)));
  EXPECT_FALSE(odo.valid());
  EXPECT_EQ(odo.counters().breaks, 1u);
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 44, zero, zero)));
  odo.Invalidate(false);
  EXPECT_FALSE(odo.AddImu(Sample(k0 + 45, zero, zero)));
}

}  // namespace
}  // namespace ppf
