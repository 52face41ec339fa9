// Moving-start estimation (moving_start.hpp) on exact and perturbed inputs: gravity, velocity
// and gyro bias from poses at scan times and the IMU of a trajectory already in motion.
#include <gtest/gtest.h>

#include <random>

#include "ppf_core/lio/moving_start.hpp"
#include "ppf_core/lio/so3.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

// A car-like motion at ~8 m/s, braking and turning, seen in a map frame that is tilted and
// yawed against gravity (the first LiDAR frame of a moving-start map is not level).
test::PoseFn Drive() {
  return [](double t) {
    const double x = 8.0 * t - 0.75 * t * t, y = 0.4 * t * t * t, z = 0.05 * std::sin(2.0 * t);
    return test::MakePose(Eigen::Vector3d(x, y, z), 0.02 * std::sin(3.0 * t),
                          0.03 * std::cos(2.5 * t), 0.3 * t * t);
  };
}

const Eigen::Matrix3d kMapFromWorld =
    test::MakePose(Eigen::Vector3d::Zero(), 0.1, -0.15, 0.7).linear();

struct Inputs {
  std::vector<ImuSample> imu;
  std::vector<MovingStartPose> poses;
};

Inputs Make(const Eigen::Vector3d& gyro_bias, double pos_noise, double rate = 200.0) {
  const test::PoseFn pose = Drive();
  Inputs in;
  for (int i = 0; i <= static_cast<int>(1.3 * rate); ++i) {
    ImuSample s = test::ImuFromPose(pose, i / rate);
    s.angular_velocity += gyro_bias;
    in.imu.push_back(s);
  }
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, pos_noise);
  for (int k = 1; k <= 11; ++k) {
    const double t = 0.1 * k + 0.003;
    const Eigen::Isometry3d T = pose(t);
    MovingStartPose p;
    p.t = t;
    p.R = kMapFromWorld * T.linear();
    p.p = kMapFromWorld * T.translation() + Eigen::Vector3d(n(rng), n(rng), n(rng));
    in.poses.push_back(p);
  }
  return in;
}

Eigen::Vector3d TrueVelocityMap(double t) {
  const test::PoseFn pose = Drive();
  return kMapFromWorld * (pose(t + 1e-5).translation() - pose(t - 1e-5).translation()) / 2e-5;
}

double TiltDeg(const Eigen::Vector3d& g_map) {
  const Eigen::Vector3d truth = kMapFromWorld * test::kGravity;
  return std::acos(std::clamp(g_map.normalized().dot(truth.normalized()), -1.0, 1.0)) * 180 / M_PI;
}

TEST(MovingStart, ExactInputsGiveGravityVelocityAndBias) {
  const Eigen::Vector3d bias(0.004, -0.003, 0.002);
  const Inputs in = Make(bias, 0.0);
  MovingStartOptions opt;
  opt.gravity = 9.81;
  const MovingStartEstimate e = EstimateMovingStart(in.imu, in.poses, opt);
  ASSERT_TRUE(e.ok) << e.reason;
  EXPECT_LT(TiltDeg(e.gravity_map), 0.01);
  EXPECT_NEAR(e.gravity_norm_free, 9.81, 1e-2);
  EXPECT_NEAR(e.gravity_map.norm(), 9.81, 1e-9);
  EXPECT_LT((e.velocity_map - TrueVelocityMap(in.poses.back().t)).norm(), 0.01);
  EXPECT_LT((e.gyro_bias - bias).norm(), 1e-4);
  EXPECT_LT(e.rms_residual, 1e-3);
  EXPECT_DOUBLE_EQ(e.acc_scale, 1.0);
}

TEST(MovingStart, CentimetreRegistrationNoiseKeepsTiltSmall) {
  const Inputs in = Make(Eigen::Vector3d::Zero(), 0.01);
  MovingStartOptions opt;
  opt.gravity = 9.81;
  const MovingStartEstimate e = EstimateMovingStart(in.imu, in.poses, opt);
  ASSERT_TRUE(e.ok) << e.reason;
  EXPECT_LT(TiltDeg(e.gravity_map), 1.0);
  EXPECT_LT((e.velocity_map - TrueVelocityMap(in.poses.back().t)).norm(), 0.1);
  EXPECT_GT(e.gravity_sigma, 0.0);
}

TEST(MovingStart, InconsistentPosesAreRefused) {
  Inputs in = Make(Eigen::Vector3d::Zero(), 0.0);
  // A registration that slipped by a metre half-way: no gravity explains it.
  for (size_t k = 5; k < in.poses.size(); ++k) in.poses[k].p += Eigen::Vector3d(1.0, 0.0, 0.0);
  MovingStartOptions opt;
  opt.gravity = 9.81;
  const MovingStartEstimate e = EstimateMovingStart(in.imu, in.poses, opt);
  EXPECT_FALSE(e.ok);
  EXPECT_FALSE(e.reason.empty());
}

TEST(MovingStart, TooFewPosesOrNoImuCoverage) {
  Inputs in = Make(Eigen::Vector3d::Zero(), 0.0);
  MovingStartOptions opt;
  std::vector<MovingStartPose> two(in.poses.begin(), in.poses.begin() + 2);
  EXPECT_FALSE(EstimateMovingStart(in.imu, two, opt).ok);
  std::vector<ImuSample> late(in.imu.begin() + 100, in.imu.end());
  EXPECT_FALSE(EstimateMovingStart(late, in.poses, opt).ok);
}

}  // namespace
}  // namespace ppf
