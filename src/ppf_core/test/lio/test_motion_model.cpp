// The constant-velocity model of LiDAR-only operation and of the IMU-loss fallback
// (motion_model.hpp): extrapolation of a constant screw motion and the tangent velocity at the
// last pose.
#include <gtest/gtest.h>

#include <cmath>

#include "ppf_core/lio/motion_model.hpp"
#include "ppf_core/lio/so3.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

using test::Deg;
using test::Pose;

// A constant body twist continues: two poses 0.5 s apart predict the third exactly, and the
// de-skew trace passes through both ends.
TEST(ConstantVelocityModel, ExtrapolatesAConstantScrewMotion) {
  const Eigen::Isometry3d step =
      Pose(Eigen::Vector3d(0.4, 0.1, 0.0), Eigen::Vector3d(0.0, 0.05, 0.3));
  const Eigen::Isometry3d T0 = Pose(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0.1, -0.2, 0.5));
  ConstantVelocityModel m;
  EXPECT_TRUE(m.Predict(5.0).isApprox(Eigen::Isometry3d::Identity()));  // nothing known yet
  m.Update(T0, 10.0);
  EXPECT_TRUE(m.Predict(10.5).isApprox(T0));  // one pose: no motion
  m.Update(T0 * step, 10.5);
  const Eigen::Isometry3d want = T0 * step * step;
  const Eigen::Isometry3d got = m.Predict(11.0);
  EXPECT_LT((got.translation() - want.translation()).norm(), 1e-9);
  EXPECT_LT(Deg(got.linear().transpose() * want.linear()), 1e-9);
  const PoseTrace trace = m.Trace();
  EXPECT_TRUE(trace.PoseAt(10.5).isApprox(T0 * step, 1e-9));
  EXPECT_LT((trace.PoseAt(11.0).translation() - want.translation()).norm(), 1e-9);
  EXPECT_LT(Deg(trace.PoseAt(11.0).linear().transpose() * want.linear()), 1e-9);
}

// Two poses 1.6 s apart on a circular bend of 35 degrees (a car whose scans were dropped): the
// velocity at the second pose is the bend's tangent there. The chord over the interval, which
// velocity_world() gives, points half the bend (17.5 degrees) off it.
TEST(ConstantVelocityModel, TangentVelocityIsTheArcsTangentAtTheLastPose) {
  const double dt = 1.6, speed = 5.0, turn = 35.0 * M_PI / 180.0;
  const Eigen::Vector3d omega(0.0, 0.0, turn / dt), v_body(speed, 0.0, 0.0);
  // The exact motion of a constant body twist over t: rotation exp(w t), translation
  // J_l(w t) v t (the arc), here in closed form for a planar turn.
  auto at = [&](double t) {
    const double r = speed / omega.z(), a = omega.z() * t;
    return Pose(Eigen::Vector3d(r * std::sin(a), r * (1.0 - std::cos(a)), 0.0),
                Eigen::Vector3d(0.0, 0.0, a));
  };
  const Eigen::Isometry3d T_world_start =
      Pose(Eigen::Vector3d(3.0, -1.0, 0.5), Eigen::Vector3d(0.02, -0.01, 0.7));
  ConstantVelocityModel m;
  m.Update(T_world_start * at(0.0), 20.0);
  m.Update(T_world_start * at(dt), 20.0 + dt);
  const Eigen::Vector3d truth = (T_world_start * at(dt)).linear() * v_body;
  const Eigen::Vector3d tangent = m.TangentVelocityWorld();
  EXPECT_LT((tangent - truth).norm(), 1e-9 * speed) << tangent.transpose();
  const double chord_off_deg =
      std::acos(m.velocity_world().normalized().dot(truth.normalized())) * 180.0 / M_PI;
  EXPECT_NEAR(chord_off_deg, 17.5, 0.01);
  // A straight interval: both are the same.
  ConstantVelocityModel straight;
  straight.Update(T_world_start, 1.0);
  straight.Update(T_world_start * Pose(Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d::Zero()), 1.1);
  EXPECT_LT((straight.TangentVelocityWorld() - straight.velocity_world()).norm(), 1e-12);
}

}  // namespace
}  // namespace ppf
