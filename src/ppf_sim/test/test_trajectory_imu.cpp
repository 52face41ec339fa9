// Ground truth and IMU must describe the same motion: integrating the noiseless IMU has to
// reproduce the ground-truth pose. Any sign, frame or derivative mistake breaks this.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "ppf_sim/imu_simulator.hpp"
#include "ppf_sim/world.hpp"

namespace ppf::sim {
namespace {

World SmallWorld(const std::string& scene, MotionKind motion, double duration) {
  WorldOptions o;
  o.scene = scene;
  o.motion = motion;
  o.motion_is_default = false;
  o.duration = duration;
  o.seed = 7;
  return BuildWorld(o);
}

TEST(Trajectory, DerivativesMatchFiniteDifferences) {
  for (MotionKind m : {MotionKind::kCar, MotionKind::kHandheld}) {
    const World w = SmallWorld("urban", m, 12.0);
    const double h = 1e-5;
    for (double t = 3.0; t < 11.0; t += 0.37) {
      const TrajectoryState s = w.trajectory.Evaluate(t);
      const TrajectoryState sp = w.trajectory.Evaluate(t + h), sm = w.trajectory.Evaluate(t - h);
      EXPECT_LT(((sp.p - sm.p) / (2 * h) - s.v).norm(), 1e-5) << "t=" << t;
      EXPECT_LT(((sp.v - sm.v) / (2 * h) - s.a).norm(), 1e-4) << "t=" << t;
      // Body rate from the rotation: R(t)^T R(t+h) ~ exp(h [omega]x).
      const Eigen::AngleAxisd d(sm.R.transpose() * sp.R);
      const Eigen::Vector3d omega_fd = d.axis() * d.angle() / (2 * h);
      EXPECT_LT((omega_fd - s.omega).norm(), 1e-4) << "t=" << t;
    }
  }
}

TEST(Trajectory, StaticStartThenMovesInEverySceneAndMotion) {
  for (const std::string& scene : SceneNames()) {
    for (MotionKind m : {MotionKind::kCar, MotionKind::kHandheld}) {
      const World w = SmallWorld(scene, m, 10.0);
      const TrajectoryState s0 = w.trajectory.Evaluate(0.0);
      for (double t = 0.0; t <= 2.5; t += 0.05) {
        const TrajectoryState s = w.trajectory.Evaluate(t);
        ASSERT_LT((s.p - s0.p).norm(), 1e-12) << scene << " t=" << t;
        ASSERT_LT((s.R - s0.R).norm(), 1e-12) << scene << " t=" << t;
        ASSERT_LT(s.v.norm(), 1e-12) << scene;
        ASSERT_LT(s.a.norm(), 1e-12) << scene;
        ASSERT_LT(s.omega.norm(), 1e-12) << scene;
      }
      EXPECT_GT(w.trajectory.Evaluate(8.0).v.norm(), 0.8) << scene;
    }
  }
}

TEST(Trajectory, SpeedsAndRatesAreInRange) {
  const World car = SmallWorld("urban", MotionKind::kCar, 40.0);
  double vmax = 0, wmax_car = 0;
  for (double t = 0; t < 40; t += 0.01) {
    const TrajectoryState s = car.trajectory.Evaluate(t);
    vmax = std::max(vmax, s.v.norm());
    wmax_car = std::max(wmax_car, s.omega.norm());
  }
  EXPECT_GT(vmax, 8.0);
  EXPECT_LT(vmax, 15.5);
  EXPECT_LT(wmax_car, 1.0);  // rad/s: curvature-limited turns
  const World hand = SmallWorld("indoor", MotionKind::kHandheld, 20.0);
  double wmax = 0, vmax_hand = 0;
  for (double t = 0; t < 20; t += 0.005) {
    const TrajectoryState s = hand.trajectory.Evaluate(t);
    wmax = std::max(wmax, s.omega.norm());
    vmax_hand = std::max(vmax_hand, s.v.norm());
  }
  EXPECT_GT(wmax * 180 / M_PI, 120.0);
  EXPECT_LT(wmax * 180 / M_PI, 260.0);
  EXPECT_LT(vmax_hand, 2.5);
}

// RK4 on (q, v, p) with step 2/rate, using the sample in between as the midpoint.
void IntegrateAndCompare(const World& w, double t0, double t1, double rate, double pos_tol,
                         double rot_tol_deg) {
  const auto imu = SimulateImu(w.trajectory, rate, t1 + 0.1, ImuNoise::Zero(), 3);
  const Eigen::Vector3d g(0, 0, -9.81);
  const int i0 = static_cast<int>(std::lround(t0 * rate));
  const int i1 = static_cast<int>(std::lround(t1 * rate));
  TrajectoryState s = w.trajectory.Evaluate(imu[i0].t);
  Eigen::Quaterniond q(s.R);
  Eigen::Vector3d v = s.v, p = s.p;
  struct D {
    Eigen::Vector4d dq;
    Eigen::Vector3d dv, dp;
  };
  auto deriv = [&](const Eigen::Quaterniond& qq, const Eigen::Vector3d& vv, const ImuMeasurement& m) {
    D d;
    const Eigen::Quaterniond w4(0, m.gyro.x(), m.gyro.y(), m.gyro.z());
    d.dq = 0.5 * (qq * w4).coeffs();
    d.dv = qq.toRotationMatrix() * m.accel + g;
    d.dp = vv;
    return d;
  };
  auto add = [](const Eigen::Quaterniond& qq, const Eigen::Vector4d& dq, double hh) {
    Eigen::Quaterniond r;
    r.coeffs() = qq.coeffs() + hh * dq;
    return r;
  };
  for (int i = i0; i + 2 <= i1; i += 2) {
    const double h = imu[i + 2].t - imu[i].t;
    const D k1 = deriv(q, v, imu[i]);
    const D k2 = deriv(add(q, k1.dq, h / 2), v + h / 2 * k1.dv, imu[i + 1]);
    const D k3 = deriv(add(q, k2.dq, h / 2), v + h / 2 * k2.dv, imu[i + 1]);
    const D k4 = deriv(add(q, k3.dq, h), v + h * k3.dv, imu[i + 2]);
    p += h / 6 * (k1.dp + 2 * k2.dp + 2 * k3.dp + k4.dp);
    v += h / 6 * (k1.dv + 2 * k2.dv + 2 * k3.dv + k4.dv);
    q.coeffs() += h / 6 * (k1.dq + 2 * k2.dq + 2 * k3.dq + k4.dq);
    q.normalize();
  }
  const int iend = i0 + ((i1 - i0) / 2) * 2;
  const TrajectoryState gt = w.trajectory.Evaluate(imu[iend].t);
  const double rot_err = Eigen::AngleAxisd(gt.R.transpose() * q.toRotationMatrix()).angle();
  EXPECT_LT((p - gt.p).norm(), pos_tol) << "travelled " << (gt.p - s.p).norm() << " m";
  EXPECT_LT(rot_err * 180 / M_PI, rot_tol_deg);
  EXPECT_LT((v - gt.v).norm(), pos_tol);
  EXPECT_GT((gt.p - s.p).norm(), 5.0);  // it did move
}

TEST(ImuGroundTruth, NoiselessCarImuReproducesPose) {
  const World w = SmallWorld("urban", MotionKind::kCar, 12.0);
  IntegrateAndCompare(w, 2.0, 10.0, 200.0, 2e-3, 0.01);
}

TEST(ImuGroundTruth, NoiselessHandheldImuReproducesPose) {
  const World w = SmallWorld("indoor", MotionKind::kHandheld, 12.0);
  IntegrateAndCompare(w, 2.0, 10.0, 400.0, 5e-3, 0.05);
}

// --moving-start: the first sample is in motion, and integrating from t = 0 (the seam where the
// planned curve was cut) still lands on the ground truth.
World MovingWorld(const std::string& scene, MotionKind motion, double duration) {
  WorldOptions o;
  o.scene = scene;
  o.motion = motion;
  o.motion_is_default = false;
  o.duration = duration;
  o.moving_start = true;
  o.seed = 7;
  return BuildWorld(o);
}

TEST(Trajectory, MovingStartIsAtCruiseSpeedAtTimeZero) {
  for (const std::string& scene : SceneNames()) {
    for (MotionKind m : {MotionKind::kCar, MotionKind::kHandheld}) {
      const World w = MovingWorld(scene, m, 10.0);
      EXPECT_GT(w.start_offset, 1.0) << scene;
      EXPECT_GE(w.trajectory.end_time(), 10.0) << scene;
      const TrajectoryState s0 = w.trajectory.Evaluate(0.0);
      // Curvature and lateral-acceleration limits slow turns below cruise speed (this urban car
      // is entering one at t = 0).
      EXPECT_GT(s0.v.norm(), 0.3 * w.speed) << scene;
      // Same curve as the static-start planning, shifted: the state at 0 is the shifted one.
      const TrajectoryState s1 = w.trajectory.Evaluate(1e-3);
      EXPECT_LT(((s1.p - s0.p) / 1e-3 - s0.v).norm(), 1e-2 * (1.0 + s0.a.norm())) << scene;
    }
  }
}

TEST(ImuGroundTruth, MovingStartCarImuReproducesPose) {
  const World w = MovingWorld("urban", MotionKind::kCar, 12.0);
  ASSERT_GT(w.trajectory.Evaluate(0.0).v.norm(), 3.0);
  IntegrateAndCompare(w, 0.0, 8.0, 200.0, 2e-3, 0.01);
}

TEST(ImuGroundTruth, MovingStartHandheldImuReproducesPose) {
  const World w = MovingWorld("indoor", MotionKind::kHandheld, 12.0);
  ASSERT_GT(w.trajectory.Evaluate(0.0).v.norm(), 0.6);
  // Fully faded-in shakes from the first sample: the body turns fast at t = 0.
  ASSERT_GT(w.trajectory.Evaluate(0.0).omega.norm(), 0.05);
  IntegrateAndCompare(w, 0.0, 8.0, 400.0, 5e-3, 0.05);
}

TEST(ImuGroundTruth, StaticImuMeasuresGravityAndNoise) {
  const World w = SmallWorld("park", MotionKind::kCar, 4.0);
  const auto clean = SimulateImu(w.trajectory, 200.0, 2.0, ImuNoise::Zero(), 1);
  ASSERT_EQ(clean.size(), 401u);
  for (const auto& m : clean) {
    EXPECT_NEAR(m.accel.norm(), 9.81, 1e-9);
    EXPECT_LT(m.gyro.norm(), 1e-12);
  }
  ImuNoise n;
  n.gyro_bias_init = n.accel_bias_init = 0.0;
  n.gyro_bias_rw = n.accel_bias_rw = 0.0;
  const auto noisy = SimulateImu(w.trajectory, 200.0, 2.0, n, 1);
  double var = 0;
  for (size_t i = 0; i < noisy.size(); ++i) var += (noisy[i].gyro - clean[i].gyro).squaredNorm();
  const double sigma = std::sqrt(var / (3.0 * noisy.size()));
  EXPECT_NEAR(sigma, n.gyro_noise * std::sqrt(200.0), 0.15 * n.gyro_noise * std::sqrt(200.0));
}

}  // namespace
}  // namespace ppf::sim
