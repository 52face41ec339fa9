// Midpoint IMU integration against an analytic trajectory, and covariance propagation.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include <Eigen/Eigenvalues>

#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/so3.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

// Helix: p = (r cos wt, r sin wt, h sin vt), heading along the tangent, exact derivatives.
struct Helix {
  double r = 5.0, w = 0.8, h = 0.5, v = 1.3;
  Eigen::Vector3d P(double t) const {
    return {r * std::cos(w * t), r * std::sin(w * t), h * std::sin(v * t)};
  }
  Eigen::Vector3d V(double t) const {
    return {-r * w * std::sin(w * t), r * w * std::cos(w * t), h * v * std::cos(v * t)};
  }
  Eigen::Vector3d A(double t) const {
    return {-r * w * w * std::cos(w * t), -r * w * w * std::sin(w * t),
            -h * v * v * std::sin(v * t)};
  }
  Eigen::Matrix3d R(double t) const {
    return Eigen::AngleAxisd(w * t + test::kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  ImuSample Imu(double t) const {
    ImuSample s;
    s.stamp_s = t;
    s.angular_velocity = Eigen::Vector3d(0, 0, w);
    s.linear_acceleration = R(t).transpose() * (A(t) - test::kGravity);
    return s;
  }
};

TEST(ImuPropagation, MidpointMatchesAnalyticHelixOverFiveSeconds) {
  const Helix helix;
  std::vector<ImuSample> samples;
  const double rate = 200.0, duration = 5.0;
  for (int i = 0; i <= static_cast<int>(duration * rate) + 1; ++i) samples.push_back(helix.Imu(i / rate));

  NavState s;
  s.stamp_s = 0.0;
  s.R_world_imu = helix.R(0);
  s.p_world_imu = helix.P(0);
  s.v_world = helix.V(0);
  s.gravity_world = test::kGravity;
  PoseTrace trace;
  // Propagate scan by scan (10 Hz) as the filter does.
  for (int k = 1; k <= 50; ++k) PropagateImu(samples, 0.1 * k, 1.0, ImuNoise(), &s, &trace);

  EXPECT_NEAR(s.stamp_s, duration, 1e-12);
  const double pos_err = (s.p_world_imu - helix.P(duration)).norm();
  const double rot_err = SO3Log(helix.R(duration).transpose() * s.R_world_imu).norm();
  const double vel_err = (s.v_world - helix.V(duration)).norm();
  // Over 5 s and ~20 m of helix at 4 m/s^2 centripetal acceleration.
  EXPECT_LT(pos_err, 5e-3) << "position error " << pos_err;
  EXPECT_LT(vel_err, 2e-3) << "velocity error " << vel_err;
  EXPECT_LT(rot_err, 1e-9) << "rotation error " << rot_err;

  // The trace reproduces the analytic pose between IMU samples too.
  for (double t : {0.0123, 1.2345, 3.33333, 4.999}) {
    const Eigen::Isometry3d T = trace.PoseAt(t);
    EXPECT_LT((T.translation() - helix.P(t)).norm(), 5e-3) << t;
    EXPECT_LT(SO3Log(helix.R(t).transpose() * T.linear()).norm(), 1e-9) << t;
  }
}

TEST(ImuPropagation, BiasesAreRemoved) {
  const Helix helix;
  const Eigen::Vector3d bg(0.01, -0.02, 0.015), ba(0.1, 0.05, -0.08);
  std::vector<ImuSample> samples;
  for (int i = 0; i <= 401; ++i) {
    ImuSample m = helix.Imu(i / 200.0);
    m.angular_velocity += bg;
    m.linear_acceleration += ba;
    samples.push_back(m);
  }
  NavState s;
  s.R_world_imu = helix.R(0);
  s.p_world_imu = helix.P(0);
  s.v_world = helix.V(0);
  s.gravity_world = test::kGravity;
  s.gyro_bias = bg;
  s.acc_bias = ba;
  PropagateImu(samples, 2.0, 1.0, ImuNoise(), &s, nullptr);
  EXPECT_LT((s.p_world_imu - helix.P(2.0)).norm(), 2e-3);
}

TEST(ImuPropagation, CovarianceGrowsAndStaysSymmetricPositive) {
  std::vector<ImuSample> samples;
  for (int i = 0; i <= 200; ++i) {
    ImuSample m;
    m.stamp_s = i / 100.0;
    m.linear_acceleration = Eigen::Vector3d(0, 0, 9.81);
    m.angular_velocity = Eigen::Vector3d(0.1, 0.0, 0.3);
    samples.push_back(m);
  }
  NavState s;
  s.gravity_world = test::kGravity;
  s.P = StateCov::Identity() * 1e-6;
  double prev_pos_var = s.P(kPos, kPos);
  for (int k = 1; k <= 20; ++k) {
    PropagateImu(samples, 0.1 * k, 1.0, ImuNoise(), &s, nullptr);
    EXPECT_GT(s.P(kPos, kPos), prev_pos_var);
    prev_pos_var = s.P(kPos, kPos);
  }
  EXPECT_LT((s.P - s.P.transpose()).norm(), 1e-12);
  const Eigen::SelfAdjointEigenSolver<StateCov> es(s.P);
  EXPECT_GT(es.eigenvalues().minCoeff(), 0.0);
  // Velocity uncertainty from accel noise over 2 s: sigma_a^2 * t (plus bias/tilt terms).
  EXPECT_GT(s.P(kVel, kVel), 0.1 * 0.1 * 2.0);
}

// The transition's block form is the dense F P F^T, for a full (every block coupled) covariance.
TEST(ImuPropagation, BlockTransitionEqualsTheDenseProduct) {
  std::srand(7);
  const StateCov A = StateCov::Random();
  const StateCov P = A * A.transpose() + StateCov::Identity();
  ImuTransition F;
  F.rot_rot = SO3Exp(Eigen::Vector3d(0.01, -0.02, 0.03));
  F.dt = 0.005;
  F.vel_rot = Eigen::Matrix3d::Random();
  F.vel_ba = Eigen::Matrix3d::Random();
  F.vel_grav = Eigen::Matrix<double, 3, 2>::Random();
  const StateCov dense = F.Dense() * P * F.Dense().transpose();
  EXPECT_LT((F.Apply(P) - dense).cwiseAbs().maxCoeff(), 1e-12 * dense.cwiseAbs().maxCoeff());
  // Each off-identity block matters: dropping one is seen.
  ImuTransition no_grav = F;
  no_grav.vel_grav.setZero();
  EXPECT_GT((no_grav.Apply(P) - dense).cwiseAbs().maxCoeff(), 1e-3);
}

// SO3Exp (series below 0.1 rad, sincos above) against Eigen's angle-axis over the whole range,
// both sides of the switch included.
TEST(So3, ExpMatchesAngleAxisAcrossTheSeriesSwitch) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  for (double angle : {1e-12, 1e-6, 1e-3, 0.05, 0.0999999, 0.1000001, 0.5, 2.0, 3.1}) {
    const Eigen::Matrix3d R = SO3Exp(angle * axis);
    const Eigen::Matrix3d ref = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    EXPECT_LT((R - ref).cwiseAbs().maxCoeff(), 1e-15) << angle;
    EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-15)
        << angle;
    EXPECT_NEAR(SO3Log(R).dot(axis), angle, 1e-12) << angle;
  }
}

TEST(ImuPropagation, InterpolationAndHoldBeyondEnds) {
  std::vector<ImuSample> samples(2);
  samples[0].stamp_s = 1.0;
  samples[0].angular_velocity = Eigen::Vector3d(0, 0, 1);
  samples[1].stamp_s = 2.0;
  samples[1].angular_velocity = Eigen::Vector3d(0, 0, 3);
  EXPECT_NEAR(InterpolateImu(samples, 1.25).angular_velocity.z(), 1.5, 1e-12);
  EXPECT_NEAR(InterpolateImu(samples, 0.0).angular_velocity.z(), 1.0, 1e-12);
  EXPECT_NEAR(InterpolateImu(samples, 5.0).angular_velocity.z(), 3.0, 1e-12);
}

// A gyro turning about z at 3 rad/s whose z axis clips at its 2 rad/s full scale for 0.2 s: the
// clipped readings are flagged (none without a configured full scale); the turn the clipping hid
// is added to the rotation covariance about z only, and putting the measured excess back into
// the readings restores the true turn.
TEST(ImuPropagation, SaturatedGyroWidensTheTurnItHidAndTheExcessRestoresIt) {
  std::vector<ImuSample> samples;
  for (int i = 0; i <= 40; ++i) {
    ImuSample s;
    s.stamp_s = 0.005 * i;
    s.angular_velocity = Eigen::Vector3d(0.01 * std::sin(i), 0.02 * std::cos(i), 3.0);
    s.linear_acceleration = -test::kGravity + Eigen::Vector3d(0.001 * i, 0, 0);
    samples.push_back(s);
  }
  std::vector<ImuSample> clipped = samples;
  for (ImuSample& s : clipped) s.angular_velocity.z() = std::min(s.angular_velocity.z(), 2.0);

  const std::vector<uint8_t> configured = SaturatedGyroAxes(clipped, 2.0);
  for (size_t i = 0; i < clipped.size(); ++i) EXPECT_EQ(configured[i], 1u << 2) << i;
  EXPECT_EQ(SaturatedGyroAxes(clipped, 0.0), std::vector<uint8_t>(clipped.size(), 0));
  EXPECT_EQ(SaturatedGyroAxes(samples, 4.0), std::vector<uint8_t>(samples.size(), 0));

  ImuNoise noise;
  noise.gyro_range = 2.0;
  auto run = [&](const std::vector<ImuSample>& in, GyroSaturation* sat) {
    NavState s;
    s.gravity_world = test::kGravity;
    s.P = StateCov::Identity() * 1e-8;
    PropagateImu(in, 0.2, 1.0, noise, &s, nullptr, sat);
    return s;
  };
  GyroSaturation sat;
  const NavState truth = run(samples, nullptr);
  const NavState hidden = run(clipped, &sat);
  EXPECT_NEAR(sat.seconds, 0.2, 1e-9);
  EXPECT_NEAR(sat.reading(4), 2.0, 1e-12);  // z, positive
  EXPECT_NEAR(sat.turn_per_rate.col(4).z(), 0.2, 1e-9);
  // One sigma: half the reading over 0.2 s, about z; x and y keep the gyro's white noise.
  EXPECT_NEAR(std::sqrt(hidden.P(kRot + 2, kRot + 2)), 0.5 * 2.0 * 0.2, 1e-3);
  EXPECT_LT(hidden.P(kRot, kRot), 1e-4);
  const double hidden_turn = SO3Log(truth.R_world_imu.transpose() * hidden.R_world_imu).norm();
  EXPECT_NEAR(hidden_turn, 0.2, 1e-6);

  Eigen::Matrix<double, 6, 1> excess = Eigen::Matrix<double, 6, 1>::Zero();
  excess(4) = 1.0;
  AddUnmeasuredRate(excess, 2.0, &clipped);
  const NavState restored = run(clipped, nullptr);
  EXPECT_LT(SO3Log(truth.R_world_imu.transpose() * restored.R_world_imu).norm(), 1e-9);
}

}  // namespace
}  // namespace ppf
