// Static IMU initialization: gravity direction and magnitude, g-unit detection, gyro bias,
// gravity-aligned world frame with yaw 0, restart on motion.
#include <gtest/gtest.h>

#include <random>

#include "ppf_core/lio/imu_init.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

// A static IMU tilted by roll/pitch (any yaw), with gyro bias and noise.
std::vector<ImuSample> StaticSamples(double roll, double pitch, double yaw, double unit,
                                     const Eigen::Vector3d& gyro_bias, double rate, double secs) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Matrix3d R = test::MakePose(Eigen::Vector3d::Zero(), roll, pitch, yaw).linear();
  std::vector<ImuSample> out;
  for (int i = 0; i <= static_cast<int>(secs * rate); ++i) {
    ImuSample s;
    s.stamp_s = 100.0 + i / rate;
    s.angular_velocity = gyro_bias + 0.002 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    s.linear_acceleration =
        (R.transpose() * (-test::kGravity) + 0.02 * Eigen::Vector3d(n(rng), n(rng), n(rng))) /
        unit;
    out.push_back(s);
  }
  return out;
}

TEST(ImuInit, GravityAlignedFrameAndGyroBias) {
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  const double roll = 0.2, pitch = -0.1;
  ImuInitializer init;
  ImuInitializer::State st = ImuInitializer::State::kCollecting;
  int used = 0;
  for (const ImuSample& s : StaticSamples(roll, pitch, 0.7, 1.0, bias, 200.0, 2.0)) {
    st = init.Add(s);
    ++used;
    if (st == ImuInitializer::State::kDone) break;
  }
  ASSERT_EQ(st, ImuInitializer::State::kDone);
  EXPECT_NEAR(used / 200.0, 1.0, 0.01);  // documented: 1 s of data
  EXPECT_NEAR(init.acc_scale(), 1.0, 1e-12);
  EXPECT_NEAR(init.gravity_world().z(), -9.81, 0.01);
  EXPECT_LT((init.gyro_bias() - bias).norm(), 1e-3);
  // Gravity aligned: the true tilt is recovered (yaw is not observable, set to zero).
  const Eigen::Matrix3d R_true = test::MakePose(Eigen::Vector3d::Zero(), roll, pitch, 0).linear();
  const Eigen::Vector3d z_true = R_true.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d z_est = init.R_world_imu().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_LT((z_true - z_est).norm(), 1e-3);
  // Minimal rotation: its axis is horizontal, i.e. no rotation about the world z (yaw 0).
  const Eigen::AngleAxisd aa(init.R_world_imu());
  EXPECT_NEAR(aa.axis().z() * aa.angle(), 0.0, 1e-9);
}

TEST(ImuInit, DetectsAccelerometerInG) {
  ImuInitializer init;
  ImuInitializer::State st = ImuInitializer::State::kCollecting;
  for (const ImuSample& s :
       StaticSamples(0.0, 0.0, 0.0, 9.80665, Eigen::Vector3d::Zero(), 100.0, 1.5)) {
    st = init.Add(s);
    if (st == ImuInitializer::State::kDone) break;
  }
  ASSERT_EQ(st, ImuInitializer::State::kDone);
  EXPECT_DOUBLE_EQ(init.acc_scale(), 9.80665);
  EXPECT_NEAR(init.gravity_world().z(), -9.81, 0.01);
}

TEST(ImuInit, MotionRestartsCollection) {
  ImuInitializer init;
  bool restarted = false;
  // Shaking: acceleration swings of 2 m/s^2 during the first second.
  for (int i = 0; i <= 200; ++i) {
    ImuSample s;
    s.stamp_s = i / 200.0;
    s.linear_acceleration = Eigen::Vector3d(2.0 * std::sin(20.0 * s.stamp_s), 0.0, 9.81);
    if (init.Add(s) == ImuInitializer::State::kRestarted) restarted = true;
  }
  EXPECT_TRUE(restarted);
  EXPECT_FALSE(init.done());
  EXPECT_NE(init.reason().find("motion"), std::string::npos) << init.reason();
  // Then the robot stands still: initialization succeeds on the next static second.
  bool done = false;
  for (int i = 1; i <= 250 && !done; ++i) {
    ImuSample s;
    s.stamp_s = 1.0 + i / 200.0;
    s.linear_acceleration = Eigen::Vector3d(0.0, 0.0, 9.81);
    done = init.Add(s) == ImuInitializer::State::kDone;
  }
  EXPECT_TRUE(done);
}

TEST(ImuInit, WorksAtFiftyHertz) {
  ImuInitializer init;
  bool done = false;
  for (const ImuSample& s :
       StaticSamples(0.0, 0.0, 0.0, 1.0, Eigen::Vector3d::Zero(), 50.0, 1.5)) {
    if (init.Add(s) == ImuInitializer::State::kDone) done = true;
  }
  EXPECT_TRUE(done);
}

// A car in a steady turn (6 m/s at 0.17 rad/s, a 35 m radius) shows no spread at all: the gyro
// reads the turn rate plus bias, the accelerometer gravity plus the centripetal 1 m/s^2, both
// constant. Taking that for rest made the turn rate a "gyro bias" and tilted the world by 6 deg.
std::vector<ImuSample> SteadyMotion(const Eigen::Vector3d& gyro, const Eigen::Vector3d& acc_body) {
  std::vector<ImuSample> out;
  for (int i = 0; i <= 300; ++i) {
    ImuSample s;
    s.stamp_s = 50.0 + i / 200.0;
    s.angular_velocity = gyro;
    s.linear_acceleration = acc_body - test::kGravity;  // body level: R = I
    out.push_back(s);
  }
  return out;
}

ImuInitializer::State Feed(ImuInitializer* init, const std::vector<ImuSample>& samples) {
  ImuInitializer::State last = ImuInitializer::State::kCollecting;
  for (const ImuSample& s : samples) {
    last = init->Add(s);
    if (last != ImuInitializer::State::kCollecting) return last;
  }
  return last;
}

TEST(ImuInit, SteadyTurnIsNotRest) {
  ImuInitializer init;
  const double v = 6.0, w = 0.17;
  EXPECT_EQ(Feed(&init, SteadyMotion(Eigen::Vector3d(0, 0, w), Eigen::Vector3d(0, v * w, 0))),
            ImuInitializer::State::kRestarted);
  EXPECT_FALSE(init.done());
  EXPECT_NE(init.reason().find("steady motion during IMU initialization (gyro mean 0.17"),
            std::string::npos)
      << init.reason();
}

TEST(ImuInit, SteadyAccelerationIsNotRest) {
  ImuInitializer init;  // 3 m/s^2 straight ahead: |a| = 10.26 m/s^2
  EXPECT_EQ(Feed(&init, SteadyMotion(Eigen::Vector3d::Zero(), Eigen::Vector3d(3.0, 0, 0))),
            ImuInitializer::State::kRestarted);
  EXPECT_NE(init.reason().find("differs from gravity 9.806650 by more than 0.300000"), std::string::npos)
      << init.reason();
  // Rest afterwards still initializes, with a plausible bias and the stated local gravity.
  ImuInitOptions o;
  o.gravity = 9.81;
  ImuInitializer at_rest(o);
  EXPECT_EQ(Feed(&at_rest, SteadyMotion(Eigen::Vector3d(0.02, -0.03, 0.01), Eigen::Vector3d::Zero())),
            ImuInitializer::State::kDone);
  EXPECT_LT((at_rest.gyro_bias() - Eigen::Vector3d(0.02, -0.03, 0.01)).norm(), 1e-12);
}

}  // namespace
}  // namespace ppf
