// PPF inside the LIO pipeline (Mode::kPpf with the built-in skeleton tracker): a spinning 16-beam
// LiDAR with per-point time moving through the synthetic box room of the core's end-to-end test.
// Checks: the facade runs PPF by default in kPpf, skeleton points get skeleton residuals, only
// scattered points enter the map (smaller than kKnn's), the trajectory is as accurate as kKnn's
// bound (0.5 % of the path), and the published skeleton planes keep their track ids.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <random>
#include <set>

#include "ppf_core/config.hpp"
#include "ppf_core/lio_ppf.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

struct SimRun {
  Trajectory est, gt;
  std::vector<ScanResult> results;
};

SimRun Simulate(Config config, double duration, int threads = 1) {
  const test::PoseFn pose = test::WiggleTrajectory(1.2);
  const test::Scene scene = test::MakeRoomScene();
  test::LidarModel lidar;
  lidar.range_noise = 0.01;
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  config.extrinsic.T_imu_lidar = test::MakePose(Eigen::Vector3d(0.1, -0.05, 0.2), 0, 0, 0.2);
  config.num_threads = threads;
  LioPpf lio(config);
  SimRun out;
  double t_imu = 0.0;
  for (double t_scan = 0.0; t_scan + lidar.period <= duration; t_scan += lidar.period) {
    const auto pts =
        test::SimulateScan(scene, pose, config.extrinsic.T_imu_lidar, t_scan, lidar, &rng);
    while (t_imu <= t_scan + lidar.period + 1e-9) {
      ImuSample s = test::ImuFromPose(pose, t_imu);
      s.angular_velocity +=
          Eigen::Vector3d(0.003, -0.002, 0.004) + 0.002 * Eigen::Vector3d(n(rng), n(rng), n(rng));
      s.linear_acceleration += 0.02 * Eigen::Vector3d(n(rng), n(rng), n(rng));
      lio.AddImu(s);
      t_imu += 1.0 / 200.0;
    }
    const test::CloudBuffer cloud =
        test::MakeCloud(pts, t_scan, pts.back().t, test::TimeEncoding{});
    lio.AddScan(cloud.view);
    for (const ScanResult& r : lio.Process()) out.results.push_back(r);
  }
  for (const ScanResult& r : lio.Process(true)) out.results.push_back(r);
  for (const ScanResult& r : out.results) {
    if (!r.pose_valid) continue;
    out.est.push_back({r.stamp_s, r.T_world_imu});
    out.gt.push_back({r.stamp_s, pose(r.stamp_s)});
  }
  return out;
}

double ApeRmse(const SimRun& run) {
  EvalOptions eo;
  eo.align = Alignment::kSE3;
  const EvalResult ape = ComputeApe(run.gt, run.est, eo);
  EXPECT_TRUE(ape.ok) << ape.error;
  return ape.stats.rmse;
}

void RunPpf(bool incremental) {
  Config config;
  config.mode = Mode::kPpf;
  config.ppf = PpfConfigForBeams(16);
  config.ppf.incremental_fitting = incremental;
  const SimRun run = Simulate(config, 8.0);
  ASSERT_GT(run.est.size(), 60u);

  size_t with_skeleton = 0, skeleton_rows = 0, map_rows_ok = 0, registered = 0;
  std::map<int64_t, int> floor_ids;  // track id -> scans in which it was the floor
  for (const ScanResult& r : run.results) {
    if (!r.pose_valid || r.reason.find("map initialized") != std::string::npos) continue;
    ++registered;
    EXPECT_EQ(r.skeleton_points + r.scattered_points + r.discarded_points, r.downsampled_points);
    map_rows_ok += r.map_inserted == r.scattered_points;  // only Theta enters the map
    with_skeleton += r.skeleton_points > 0;
    skeleton_rows += r.skeleton_residuals > 0;
    EXPECT_LE(r.skeleton_planes.size(), 5u);
    for (const SkeletonPlane& sp : r.skeleton_planes) {
      // The room floor is z = -2 in the world (which starts at the IMU's initial pose).
      if (sp.missed_scans == 0 && std::abs(sp.plane.n.z()) > 0.99 &&
          std::abs(std::abs(sp.plane.d) - 2.0) < 0.1) {
        ++floor_ids[sp.track_id];
      }
    }
  }
  EXPECT_EQ(map_rows_ok, registered);
  EXPECT_GE(with_skeleton, registered - 1);
  EXPECT_GE(skeleton_rows, registered - 2);  // the first PPF scan has an empty window
  // The floor is one physical plane: one track id for (nearly) the whole run.
  ASSERT_FALSE(floor_ids.empty());
  int best = 0;
  for (const auto& [id, scans] : floor_ids) best = std::max(best, scans);
  EXPECT_GE(best, static_cast<int>(registered) - 3);

  const double rmse = ApeRmse(run);
  const double length = PathLength(run.gt);
  std::printf(
      "[ppf %s] scans %zu, path %.2f m, APE(se3) rmse %.4f m (%.3f%%), floor track ids %zu\n",
      incremental ? "incremental" : "ransac", run.est.size(), length, rmse, 100.0 * rmse / length,
      floor_ids.size());
  EXPECT_LT(rmse, 0.005 * length);
}

TEST(PpfPipeline, KppfRunsSkeletonTrackingAndStaysAccurate) { RunPpf(false); }
TEST(PpfPipeline, KppfWithIncrementalFitting) { RunPpf(true); }

TEST(PpfPipeline, MapIsSmallerThanKnnMode) {
  Config knn_config;
  const SimRun knn = Simulate(knn_config, 4.0);
  Config ppf_config;
  ppf_config.mode = Mode::kPpf;
  const SimRun ppf = Simulate(ppf_config, 4.0);
  ASSERT_FALSE(knn.results.empty());
  ASSERT_FALSE(ppf.results.empty());
  const size_t knn_map = knn.results.back().map_size, ppf_map = ppf.results.back().map_size;
  std::printf(
      "[ppf] map after 4 s: kNN %zu points, PPF %zu points (%.0f%%); APE rmse kNN %.4f m, "
      "PPF %.4f m\n",
      knn_map, ppf_map, 100.0 * ppf_map / std::max<size_t>(1, knn_map), ApeRmse(knn), ApeRmse(ppf));
  EXPECT_LT(ppf_map, knn_map);
}

// On two threads the pre-fit has the kNN searches beside it (KnnResidualProvider::Prefetch) and
// the rows of each IEKF iteration come from one team; the trajectory, the kNN map and the
// skeleton's window and patches are bit for bit the one thread's.
TEST(PpfPipeline, TwoThreadsGiveTheOneThreadTrajectoryBitForBit) {
  Config config;
  config.mode = Mode::kPpf;
  config.ppf = PpfConfigForBeams(16);
  const SimRun one = Simulate(config, 3.0, 1);
  const SimRun two = Simulate(config, 3.0, 2);
  ASSERT_GT(one.est.size(), 15u);
  ASSERT_EQ(one.est.size(), two.est.size());
  for (size_t i = 0; i < one.est.size(); ++i) {
    EXPECT_EQ(one.est[i].stamp_s, two.est[i].stamp_s);
    EXPECT_TRUE(one.est[i].T.matrix() == two.est[i].T.matrix()) << "scan " << i;
  }
  ASSERT_EQ(one.results.size(), two.results.size());
  for (size_t i = 0; i < one.results.size(); ++i) {
    const ScanResult &a = one.results[i], &b = two.results[i];
    EXPECT_EQ(a.map_inserted, b.map_inserted) << "scan " << i;
    EXPECT_EQ(a.map_size, b.map_size) << "scan " << i;
    EXPECT_EQ(a.skeleton_patches, b.skeleton_patches) << "scan " << i;
    ASSERT_EQ(a.skeleton_planes.size(), b.skeleton_planes.size()) << "scan " << i;
    for (size_t k = 0; k < a.skeleton_planes.size(); ++k) {
      EXPECT_EQ(a.skeleton_planes[k].track_id, b.skeleton_planes[k].track_id) << "scan " << i;
      EXPECT_TRUE(a.skeleton_planes[k].plane.n == b.skeleton_planes[k].plane.n) << "scan " << i;
    }
  }
}

TEST(PpfPipeline, YamlPpfSectionReachesTheConfig) {
  Config c;
  ConfigLoadReport r =
      LoadConfigYamlString("mode: ppf\nppf:\n  beams: 64\n  delta: 0.12\n  typo_key: 1\n", &c);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(c.mode, Mode::kPpf);
  EXPECT_EQ(c.ppf.plane_least_inliers, 400);
  EXPECT_TRUE(c.ppf.incremental_fitting);
  EXPECT_DOUBLE_EQ(c.ppf.delta, 0.12);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("ppf.typo_key"), std::string::npos);
  // No ppf section: every PPF default, no crash (the reference crashed on missing keys).
  Config d;
  r = LoadConfigYamlString("mode: ppf\n", &d);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(d.ppf.plane_least_inliers, PpfConfig{}.plane_least_inliers);
  // A wrong type fails the whole load and names the key.
  Config e;
  r = LoadConfigYamlString("ppf:\n  max_planes_per_scan: [5]\n", &e);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("ppf.max_planes_per_scan"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace ppf
