// LiDAR-only building blocks: the constant-velocity model and the coarse alignment from several
// guesses. The facade's LiDAR-only runs are in test_end_to_end (synthetic room) and
// ppf_tools' test_lidar_only_real / test_accuracy.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ppf_core/lio/hypothesis_search.hpp"
#include "ppf_core/lio/motion_model.hpp"
#include "ppf_core/lio/so3.hpp"
#include "ppf_core/lio/voxel_map.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

double Deg(const Eigen::Matrix3d& R) { return SO3Log(R).norm() * 180.0 / M_PI; }

Eigen::Isometry3d Pose(const Eigen::Vector3d& p, const Eigen::Vector3d& rotvec) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = SO3Exp(rotvec);
  T.translation() = p;
  return T;
}

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

struct RoomFixture {
  test::Scene scene = test::MakeRoomScene();
  test::LidarModel lidar;
  VoxelMap map{VoxelMapOptions()};
  ScanFrame frame;

  RoomFixture() { lidar.rings = 32; }

  std::vector<Eigen::Vector3f> Scan(const Eigen::Isometry3d& T_world_lidar) const {
    const test::PoseFn pose = [&](double) { return T_world_lidar; };
    std::vector<Eigen::Vector3f> out;
    for (const auto& sp :
         test::SimulateScan(scene, pose, Eigen::Isometry3d::Identity(), 0.0, lidar)) {
      out.push_back(sp.p);
    }
    return out;
  }
  // The map from a scan at the origin; frame = a scan at T_world_lidar, thinned like a 0.5 m grid.
  void Build(const Eigen::Isometry3d& T_world_lidar) {
    for (const Eigen::Vector3f& p : Scan(Eigen::Isometry3d::Identity())) map.Insert(p);
    const std::vector<Eigen::Vector3f> pts = Scan(T_world_lidar);
    for (size_t i = 0; i < pts.size(); i += 4) frame.points_lidar.push_back(pts[i]);
    frame.labels.assign(frame.points_lidar.size(), PointLabel::kScattered);
    frame.map = &map;
  }
};

// The sensor turned 30 degrees more than the model said: aligned from the model's guess alone,
// registration stays far off (the turn exceeds the kNN reach); with the turned guesses it finds
// the true pose, and the fit tells the two apart.
TEST(AlignHypotheses, RecoversATurnTheModelMissed) {
  RoomFixture f;
  const Eigen::Isometry3d truth =
      Pose(Eigen::Vector3d(0.3, -0.2, 0.05), Eigen::Vector3d(0, 0, 0.52));
  f.Build(truth);
  const Eigen::Isometry3d model =
      Pose(Eigen::Vector3d(0.3, -0.2, 0.05), Eigen::Vector3d(0, 0, 0.0));
  LidarOnlyOptions options;
  const IekfOptions iekf;
  const KnnOptions knn;

  const CoarseAlignment alone = AlignHypotheses(f.frame, {{"model", model}}, options, iekf, knn);
  EXPECT_EQ(alone.tried, 1);
  EXPECT_GT(Deg(alone.T_world_lidar.linear().transpose() * truth.linear()), 5.0);
  EXPECT_LT(alone.fit, options.min_fit);

  std::vector<MotionHypothesis> guesses = {{"model", model}};
  for (double deg : {15.0, -15.0, 30.0, -30.0}) {
    Eigen::Isometry3d turned = model;
    turned.linear() = model.linear() * SO3Exp(Eigen::Vector3d(0, 0, deg * M_PI / 180.0));
    guesses.push_back({"turn " + std::to_string(static_cast<int>(deg)), turned});
  }
  const CoarseAlignment c = AlignHypotheses(f.frame, guesses, options, iekf, knn);
  EXPECT_LT(Deg(c.T_world_lidar.linear().transpose() * truth.linear()), 0.2) << c.name;
  EXPECT_LT((c.T_world_lidar.translation() - truth.translation()).norm(), 0.02) << c.name;
  EXPECT_GE(c.fit, options.good_fit) << c.name;
  EXPECT_GT(c.tried, 1);
}

// A guess that already fits ends the search: the others cost nothing.
TEST(AlignHypotheses, AGoodFirstGuessEndsTheSearch) {
  RoomFixture f;
  const Eigen::Isometry3d truth = Pose(Eigen::Vector3d(0.4, 0.1, 0.0), Eigen::Vector3d(0, 0, 0.1));
  f.Build(truth);
  const Eigen::Isometry3d near =
      Pose(Eigen::Vector3d(0.35, 0.12, 0.0), Eigen::Vector3d(0, 0, 0.08));
  const CoarseAlignment c =
      AlignHypotheses(f.frame, {{"model", near}, {"no motion", Eigen::Isometry3d::Identity()}},
                      LidarOnlyOptions(), IekfOptions(), KnnOptions());
  EXPECT_EQ(c.tried, 1);
  EXPECT_EQ(c.name, "model");
  EXPECT_LT((c.T_world_lidar.translation() - truth.translation()).norm(), 0.02);
}

}  // namespace
}  // namespace ppf
