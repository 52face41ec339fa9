// De-skew of a scan taken while moving fast restores the static scan to sub-centimetre.
#include <gtest/gtest.h>

#include <cmath>

#include "ppf_core/lio/deskew.hpp"
#include "ppf_core/lio/imu_propagation.hpp"
#include "ppf_core/lio/so3.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

TEST(Deskew, MovingScanMatchesStaticScanAtScanEnd) {
  // 2 m/s forward with a lateral wiggle, yawing at ~1 rad/s: points at the start of a 0.1 s
  // sweep are off by ~20 cm and several cm of rotation-induced shift without de-skew.
  const test::PoseFn pose = [](double t) {
    return test::MakePose(Eigen::Vector3d(2.0 * t, 0.3 * std::sin(2.0 * t), 0.1 * t), 0.02 * t, 0.0,
                          1.0 * t + 0.2 * std::sin(3.0 * t));
  };
  const Eigen::Isometry3d T_imu_lidar = test::MakePose(Eigen::Vector3d(0.2, 0.0, 0.1), 0, 0, 0.3);
  test::LidarModel lidar;
  lidar.azimuth_steps = 360;
  const double t0 = 1.0;
  const auto pts = test::SimulateScan(test::MakeRoomScene(), pose, T_imu_lidar, t0, lidar);
  ASSERT_GT(pts.size(), 1000u);
  const double t_end = pts.back().t;

  std::vector<TimedPoint> timed;
  for (const auto& p : pts) timed.push_back({p.p, 0.f, p.t});

  const PoseTrace trace = test::TraceFromTruth(pose, t0, t_end);

  std::vector<Eigen::Vector3f> deskewed;
  DeskewToEnd(timed, trace, t_end, T_imu_lidar, &deskewed);
  ASSERT_EQ(deskewed.size(), pts.size());

  // Truth: every point moved through the world into the LiDAR frame at t_end.
  const Eigen::Isometry3d T_lidarend_world = (pose(t_end) * T_imu_lidar).inverse();
  double max_err = 0.0, max_raw = 0.0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d truth =
        T_lidarend_world * (pose(pts[i].t) * T_imu_lidar * pts[i].p.cast<double>());
    max_err = std::max(max_err, (deskewed[i].cast<double>() - truth).norm());
    max_raw = std::max(max_raw, (pts[i].p.cast<double>() - truth).norm());
  }
  EXPECT_LT(max_err, 0.01) << "de-skewed max error " << max_err;
  EXPECT_GT(max_raw, 0.15) << "the test motion must matter";
}

TEST(Deskew, PointsAtScanEndAreUnchanged) {
  PoseTrace trace;
  ImuKnot k;
  k.t = 0.0;
  k.v = Eigen::Vector3d(1, 0, 0);
  trace.knots.push_back(k);
  k.t = 0.1;
  k.p = Eigen::Vector3d(0.1, 0, 0);
  trace.knots.push_back(k);
  std::vector<TimedPoint> pts = {{Eigen::Vector3f(1, 2, 3), 0.f, 0.1},
                                 {Eigen::Vector3f(1, 2, 3), 0.f, 0.0}};
  std::vector<Eigen::Vector3f> out;
  DeskewToEnd(pts, trace, 0.1, Eigen::Isometry3d::Identity(), &out);
  EXPECT_TRUE(out[0].isApprox(Eigen::Vector3f(1, 2, 3)));
  // Seen 0.1 m earlier along +x: at the end it lies 0.1 m further back.
  EXPECT_TRUE(out[1].isApprox(Eigen::Vector3f(0.9f, 2, 3), 1e-5f));
}

// The per-segment form of DeskewToEnd is the pose trace's own PoseAt, point by point, on a trace
// with turning, accelerating segments, and for times before its first and after its last knot.
TEST(Deskew, SegmentFormEqualsThePoseTraceAtEveryPoint) {
  PoseTrace trace;
  for (int k = 0; k <= 20; ++k) {
    ImuKnot knot;
    knot.t = 10.0 + 0.005 * k;
    knot.R = SO3Exp(Eigen::Vector3d(0.1 * k, -0.05 * k, 0.8 + 0.2 * k) * 0.01);
    knot.p = Eigen::Vector3d(3.0 + 0.04 * k, -1.0 + 0.002 * k * k, 0.5);
    knot.v = Eigen::Vector3d(8.0 + 0.1 * k, 0.4 * k, -0.3);
    knot.omega = Eigen::Vector3d(0.3, -1.5 + 0.1 * k, 2.0);  // up to 2.5 rad/s
    knot.acc_world = Eigen::Vector3d(2.0, -1.0 + 0.2 * k, 0.5);
    trace.knots.push_back(knot);
  }
  const Eigen::Isometry3d T_imu_lidar =
      test::MakePose(Eigen::Vector3d(0.2, -0.1, 0.3), 0.1, 0, 0.5);
  std::vector<TimedPoint> pts;
  for (int i = 0; i < 500; ++i) {
    const double t = 9.99 + 0.12 * i / 499.0;  // 10 ms before the first knot to 10 ms after
    pts.push_back(
        {Eigen::Vector3f(30.0f * std::cos(0.1f * i), 30.0f * std::sin(0.1f * i), -1.5f + 0.01f * i),
         0.f, t});
  }
  const double t_end = trace.knots.back().t;
  std::vector<Eigen::Vector3f> out;
  DeskewToEnd(pts, trace, t_end, T_imu_lidar, &out);
  const Eigen::Isometry3d T_lidarend_world = (trace.PoseAt(t_end) * T_imu_lidar).inverse();
  double max_err = 0.0, max_moved = 0.0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector3d ref =
        T_lidarend_world * (trace.PoseAt(pts[i].t) * (T_imu_lidar * pts[i].p.cast<double>()));
    max_err = std::max(max_err, (out[i].cast<double>() - ref).norm());
    max_moved = std::max(max_moved, (pts[i].p.cast<double>() - ref).norm());
  }
  EXPECT_LT(max_err, 1e-5);  // float output of 30 m points
  EXPECT_GT(max_moved, 0.5);
}

}  // namespace
}  // namespace ppf
