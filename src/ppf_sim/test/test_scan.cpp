#include <gtest/gtest.h>

#include <cmath>

#include "ppf_sim/imu_simulator.hpp"
#include "ppf_sim/scan_generator.hpp"
#include "ppf_sim/world.hpp"

namespace ppf::sim {
namespace {

// A trajectory moving along +x at constant speed `v` (0 = static) at height z0.
Trajectory Straight(double v, double z0) {
  std::vector<Eigen::Vector3d> pos, eul;
  for (int i = 0; i < 40; ++i) {
    pos.emplace_back(v * (i - 1) * 0.1, 0.0, z0);
    eul.emplace_back(0, 0, 0);
  }
  return Trajectory(0.1, pos, eul);
}

Eigen::Isometry3d TestExtrinsic() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(-0.04, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.25, -0.12, 0.3);
  return T;
}

// No range noise, no dropout, the test extrinsic: every point lies exactly where the pose at its
// firing time and T_imu_lidar put it.
ScanOptions ExactScanOptions() {
  ScanOptions so;
  so.range_noise = 0.0;
  so.dropout = 0.0;
  so.T_imu_lidar = TestExtrinsic();
  return so;
}

Eigen::Vector3f Xyz(const CloudBuffer& c, size_t i) {
  return {c.Get<float>(i, *c.Field("x")), c.Get<float>(i, *c.Field("y")),
          c.Get<float>(i, *c.Field("z"))};
}

TEST(LidarModel, BeamTablesMatchDatasheets) {
  struct Expect {
    const char* name;
    size_t beams;
    double lo, hi;
  };
  for (const Expect& e : {Expect{"vlp16", 16, -15.0, 15.0}, Expect{"hdl32", 32, -30.67, 10.67},
                          Expect{"hdl64", 64, -24.9, 2.0}, Expect{"os1_64", 64, -22.5, 22.5},
                          Expect{"os1_128", 128, -22.5, 22.5}}) {
    const LidarModel m = GetLidarModel(e.name);
    ASSERT_EQ(m.elevation_deg.size(), e.beams) << e.name;
    const auto [mn, mx] = std::minmax_element(m.elevation_deg.begin(), m.elevation_deg.end());
    EXPECT_NEAR(*mn, e.lo, 1e-9) << e.name;
    EXPECT_NEAR(*mx, e.hi, 1e-9) << e.name;
  }
  const LidarModel vlp = GetLidarModel("vlp16");
  for (size_t r = 1; r < 16; ++r) EXPECT_NEAR(vlp.elevation_deg[r] - vlp.elevation_deg[r - 1], 2.0, 1e-9);
  EXPECT_EQ(vlp.layout, PointLayout::kVelodyne);
  const LidarModel os = GetLidarModel("os1_64");
  EXPECT_EQ(os.layout, PointLayout::kOuster);
  EXPECT_GT(os.elevation_deg.front(), os.elevation_deg.back());  // ring 0 is the top beam
  const LidarModel hdl = GetLidarModel("hdl64");
  EXPECT_NEAR(360.0 / hdl.columns, 0.1728, 1e-3);
  EXPECT_THROW(GetLidarModel("hdl128"), std::invalid_argument);
}

class ScanFixture : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    WorldOptions o;
    o.scene = "urban";
    o.duration = 8.0;
    o.seed = 5;
    world_ = new World(BuildWorld(o));
  }
  static void TearDownTestSuite() { delete world_; }
  static World* world_;
};
World* ScanFixture::world_ = nullptr;

TEST_F(ScanFixture, PointsLieOnTheirRingsElevation) {
  for (const char* name : {"vlp16", "hdl64", "os1_128"}) {
    const LidarModel m = GetLidarModel(name);
    ScanGenerator gen(world_->scene, world_->trajectory, m, ScanOptions{});
    const CloudBuffer c = gen.Generate(60);
    const PointFieldDesc* ring = c.Field("ring");
    ASSERT_NE(ring, nullptr);
    size_t checked = 0;
    for (size_t i = 0; i < c.num_points(); i += 7) {
      const Eigen::Vector3f p = Xyz(c, i);
      if (p.norm() == 0.0f) continue;  // Ouster no-return pixel
      const double el = std::atan2(p.z(), std::hypot(p.x(), p.y())) * 180 / M_PI;
      EXPECT_NEAR(el, m.elevation_deg[c.Get<uint16_t>(i, *ring)], 1e-3) << name;
      ++checked;
    }
    EXPECT_GT(checked, 1000u) << name;
  }
}

TEST_F(ScanFixture, Hdl64ScanIsKittiSized) {
  ScanGenerator gen(world_->scene, world_->trajectory, GetLidarModel("hdl64"), ScanOptions{});
  const CloudBuffer c = gen.Generate(70);
  EXPECT_EQ(c.height, 1u);
  EXPECT_EQ(c.point_step, 32u);
  EXPECT_GT(c.width, 90000u);
  EXPECT_LT(c.width, 133300u);
  EXPECT_EQ(c.data.size(), static_cast<size_t>(c.width) * 32);
}

TEST_F(ScanFixture, VelodyneTimesSpanTheSweepAndFollowAzimuth) {
  ScanGenerator gen(world_->scene, world_->trajectory, GetLidarModel("hdl32"), ScanOptions{});
  const CloudBuffer c = gen.Generate(50);
  const PointFieldDesc* time = c.Field("time");
  ASSERT_NE(time, nullptr);
  EXPECT_EQ(time->datatype, kFloat32);
  float prev = -1.0f, tmin = 1.0f, tmax = -1.0f;
  for (size_t i = 0; i < c.num_points(); ++i) {
    const float t = c.Get<float>(i, *time);
    EXPECT_GE(t, prev);  // points are in firing order
    prev = t;
    tmin = std::min(tmin, t);
    tmax = std::max(tmax, t);
    // Clockwise spin starting behind the sensor: azimuth = pi - 2 pi t / T.
    const Eigen::Vector3f p = Xyz(c, i);
    const double az = std::atan2(p.y(), p.x());
    const double expect = M_PI - 2 * M_PI * t / 0.1;
    EXPECT_NEAR(std::remainder(az - expect, 2 * M_PI), 0.0, 1e-3);
  }
  EXPECT_LT(tmin, 0.001f);
  EXPECT_GT(tmax, 0.099f);
  EXPECT_LT(tmax, 0.1f);
}

TEST_F(ScanFixture, OusterLayoutIsOrganizedWithNanosecondTimes) {
  ScanGenerator gen(world_->scene, world_->trajectory, GetLidarModel("os1_64"), ScanOptions{});
  const CloudBuffer c = gen.Generate(50);
  EXPECT_EQ(c.height, 64u);
  EXPECT_EQ(c.width, 1024u);
  EXPECT_FALSE(c.is_dense);
  EXPECT_EQ(c.point_step, 48u);
  const PointFieldDesc* t = c.Field("t");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->datatype, kUint32);
  ASSERT_NE(c.Field("reflectivity"), nullptr);
  for (uint32_t row : {0u, 31u, 63u}) {
    EXPECT_EQ(c.Get<uint32_t>(row * 1024, *t), 0u);
    EXPECT_EQ(c.Get<uint32_t>(row * 1024 + 1023, *t), static_cast<uint32_t>(std::llround(1023 * 1e8 / 1024)));
    EXPECT_EQ(c.Get<uint16_t>(row * 1024 + 5, *c.Field("ring")), row);
  }
}

TEST_F(ScanFixture, SameSeedSameBytesOtherSeedDifferent) {
  WorldOptions o;
  o.scene = "urban";
  o.duration = 8.0;
  o.seed = 5;
  const World again = BuildWorld(o);
  o.seed = 6;
  const World other = BuildWorld(o);
  ScanOptions so;
  so.seed = 5;
  const LidarModel m = GetLidarModel("vlp16");
  const CloudBuffer a = ScanGenerator(world_->scene, world_->trajectory, m, so).Generate(40);
  const CloudBuffer b = ScanGenerator(again.scene, again.trajectory, m, so).Generate(40);
  EXPECT_EQ(a.data, b.data);
  EXPECT_EQ(a.width, b.width);
  so.seed = 6;
  const CloudBuffer d = ScanGenerator(other.scene, other.trajectory, m, so).Generate(40);
  EXPECT_NE(a.data, d.data);
  const auto ia = SimulateImu(world_->trajectory, 200, 5, ImuNoise{}, 5);
  const auto ib = SimulateImu(again.trajectory, 200, 5, ImuNoise{}, 5);
  ASSERT_EQ(ia.size(), ib.size());
  for (size_t i = 0; i < ia.size(); ++i) {
    ASSERT_EQ(ia[i].gyro, ib[i].gyro);
    ASSERT_EQ(ia[i].accel, ib[i].accel);
  }
}

// A static sensor between a wall (world x = 8) and a floor (world z = 0): every noiseless
// point mapped through T_world_imu * T_imu_lidar must land on one of the two planes.
TEST(Extrinsic, StaticScanOfKnownPlanesAppearsWhereTheExtrinsicSays) {
  Scene scene;
  scene.Add(MakeQuad({8, 0, 2}, Eigen::Vector3d::UnitY(), 50, Eigen::Vector3d::UnitZ(), 10, 0.6f));
  scene.Add(MakeQuad({0, 0, 0}, Eigen::Vector3d::UnitX(), 7.9, Eigen::Vector3d::UnitY(), 50, 0.6f));
  scene.Build();
  const Trajectory traj = Straight(0.0, 1.2);
  const ScanOptions so = ExactScanOptions();
  ScanGenerator gen(scene, traj, GetLidarModel("vlp16"), so);
  const CloudBuffer c = gen.Generate(0);
  const Eigen::Isometry3d T_world_lidar = traj.Pose(0.0) * so.T_imu_lidar;
  size_t wall = 0, floor = 0;
  double worst_ignoring_extrinsic = 0.0;
  for (size_t i = 0; i < c.num_points(); ++i) {
    const Eigen::Vector3d pl = Xyz(c, i).cast<double>();
    const Eigen::Vector3d pw = T_world_lidar * pl;
    const double d_wall = std::abs(pw.x() - 8.0), d_floor = std::abs(pw.z());
    ASSERT_LT(std::min(d_wall, d_floor), 1e-4) << pw.transpose();
    (d_wall < d_floor ? wall : floor)++;
    const Eigen::Vector3d naive = traj.Pose(0.0) * pl;
    worst_ignoring_extrinsic =
        std::max(worst_ignoring_extrinsic, std::min(std::abs(naive.x() - 8.0), std::abs(naive.z())));
  }
  EXPECT_GT(wall, 500u);
  EXPECT_GT(floor, 500u);
  EXPECT_GT(worst_ignoring_extrinsic, 0.2);  // the extrinsic is not a no-op
}

// Moving at 10 m/s towards a wall: each point is where the pose at its own firing time puts it;
// using the scan-start pose for all of them is off by up to v * T = 1 m.
TEST(MotionDistortion, PointsFollowThePoseAtTheirOwnTime) {
  Scene scene;
  scene.Add(MakeQuad({30, 0, 0}, Eigen::Vector3d::UnitY(), 100, Eigen::Vector3d::UnitZ(), 50, 0.6f));
  scene.Build();
  const Trajectory traj = Straight(10.0, 0.0);
  const ScanOptions so = ExactScanOptions();
  ScanGenerator gen(scene, traj, GetLidarModel("vlp16"), so);
  const CloudBuffer c = gen.Generate(5);
  const PointFieldDesc* time = c.Field("time");
  double worst_start_pose = 0.0;
  ASSERT_GT(c.num_points(), 1000u);
  for (size_t i = 0; i < c.num_points(); ++i) {
    const Eigen::Vector3d pl = Xyz(c, i).cast<double>();
    const double t = 0.5 + c.Get<float>(i, *time);
    const Eigen::Vector3d pw = traj.Pose(t) * so.T_imu_lidar * pl;
    ASSERT_NEAR(pw.x(), 30.0, 2e-4);
    worst_start_pose =
        std::max(worst_start_pose, std::abs((traj.Pose(0.5) * so.T_imu_lidar * pl).x() - 30.0));
  }
  EXPECT_GT(worst_start_pose, 0.3);
}

TEST(Noise, RangeNoiseHasTheRequestedSigma) {
  Scene scene;
  scene.Add(MakeQuad({10, 0, 0}, Eigen::Vector3d::UnitY(), 100, Eigen::Vector3d::UnitZ(), 50, 0.8f));
  scene.Build();
  const Trajectory traj = Straight(0.0, 0.0);
  ScanOptions so;
  so.range_noise = 0.05;
  so.dropout = 0.1;
  ScanGenerator gen(scene, traj, GetLidarModel("vlp16"), so);
  const CloudBuffer c = gen.Generate(0);
  double sum2 = 0;
  size_t n = 0;
  for (size_t i = 0; i < c.num_points(); ++i) {
    const Eigen::Vector3f p = Xyz(c, i);
    if (p.x() < 1.0 || std::abs(std::atan2(p.y(), p.x())) >= M_PI / 4) continue;
    // Range along the beam to the plane x = 10 is 10 / (direction.x).
    const double dir_x = p.x() / p.norm();
    sum2 += std::pow(p.norm() - 10.0 / dir_x, 2);
    ++n;
  }
  ASSERT_GT(n, 3000u);
  EXPECT_NEAR(std::sqrt(sum2 / n), 0.05, 0.005);
  // A quarter of the sweep (450 columns) looks at the wall within +-45 deg; 10 % dropout.
  EXPECT_NEAR(static_cast<double>(n) / (16 * 450), 0.9, 0.03);
}

}  // namespace
}  // namespace ppf::sim

namespace ppf::sim {
namespace {

// Other drivers' time conventions must describe the same firing times.
TEST(TimeConventions, StampAtEndAndAbsoluteTimesAgreeWithTheDefault) {
  WorldOptions o;
  o.duration = 5;
  const World w = BuildWorld(o);
  ScanOptions so;
  so.start_ns = 1700000000LL * 1000000000LL;
  const LidarModel m = GetLidarModel("vlp16");
  const CloudBuffer base = ScanGenerator(w.scene, w.trajectory, m, so).Generate(20);
  so.stamp_at_end = true;
  const CloudBuffer end = ScanGenerator(w.scene, w.trajectory, m, so).Generate(20);
  so.stamp_at_end = false;
  so.time_field = ScanOptions::TimeField::kAbsoluteF64;
  const CloudBuffer abs = ScanGenerator(w.scene, w.trajectory, m, so).Generate(20);
  so.time_field = ScanOptions::TimeField::kNone;
  const CloudBuffer none = ScanGenerator(w.scene, w.trajectory, m, so).Generate(20);

  EXPECT_EQ(base.stamp_ns, so.start_ns + 2000000000LL);
  EXPECT_EQ(end.stamp_ns, base.stamp_ns + 100000000LL);
  ASSERT_EQ(end.width, base.width);
  ASSERT_EQ(abs.width, base.width);
  EXPECT_EQ(none.Field("time"), nullptr);
  EXPECT_EQ(none.Field("timestamp"), nullptr);
  const PointFieldDesc* ts = abs.Field("timestamp");
  ASSERT_NE(ts, nullptr);
  EXPECT_EQ(ts->datatype, kFloat64);
  const double stamp_s = 1700000002.0;
  for (size_t i = 0; i < base.num_points(); i += 13) {
    const float t = base.Get<float>(i, *base.Field("time"));
    EXPECT_NEAR(end.Get<float>(i, *end.Field("time")), t - 0.1f, 1e-6);
    EXPECT_NEAR(abs.Get<double>(i, *ts) - stamp_s, t, 1e-6);
    EXPECT_EQ(none.Get<float>(i, *none.Field("x")), base.Get<float>(i, *base.Field("x")));
  }
}

}  // namespace
}  // namespace ppf::sim
