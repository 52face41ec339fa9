// End to end: a spinning 16-beam LiDAR with per-point time moving through a box room with
// pillars, IMU synthesized from the analytic trajectory (with noise and gyro bias); the facade's
// trajectory must stay within 0.5 % of the path length (APE RMSE, SE(3)-aligned, as evo).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "ppf_core/lio_ppf.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

struct RunOptions {
  test::TimeEncoding enc;
  double acc_unit = 1.0;  // 9.80665: the IMU reports in g
  double duration = 12.0;
  Eigen::Vector3d acc_bias = Eigen::Vector3d::Zero();  // m/s^2, added to every sample
  Eigen::Isometry3d T_imu_lidar = test::MakePose(Eigen::Vector3d(0.1, -0.05, 0.2), 0, 0, 0.2);
  // Neither IMU samples nor scans in [gap_begin, gap_begin + gap_length): a link that was down.
  double gap_begin = 0.0;
  double gap_length = 0.0;
  bool no_imu = false;  // LiDAR-only: no IMU sample is fed
  // No IMU samples in [imu_gap_begin, imu_gap_begin + imu_gap_length), the scans going on: an
  // IMU driver that crashed and came back.
  double imu_gap_begin = 0.0;
  double imu_gap_length = 0.0;
  bool imu_gap_invalid = false;  // the gap's samples arrive, but as NaN (a driver gone bad)
  double imu_begin = 0.0;  // no IMU samples before this time: a driver that starts late
  // IMU fed this far ahead of the scans: a core behind the IMU stream, its scans still queued
  // when newer IMU samples arrive.
  double imu_lead_s = 0.0;
};

struct RunOutput {
  Trajectory est, gt;
  std::vector<ScanResult> results;
};

RunOutput Simulate(const RunOptions& o, Config config) {
  const double t_static = 1.2;
  const test::PoseFn pose = test::WiggleTrajectory(t_static);
  const test::Scene scene = test::MakeRoomScene();
  test::LidarModel lidar;
  lidar.range_noise = 0.01;
  std::mt19937 rng(42);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Vector3d gyro_bias(0.003, -0.002, 0.004);

  config.extrinsic.T_imu_lidar = o.T_imu_lidar;
  // Single thread: deterministic and fair on shared CI cores (threading is not under test here).
  config.num_threads = 1;
  LioPpf lio(config);
  RunOutput out;
  double t_imu = 0.0;
  const double imu_dt = 1.0 / 200.0;
  const auto in_gap = [&o](double t) {
    return o.gap_length > 0.0 && t >= o.gap_begin && t < o.gap_begin + o.gap_length;
  };
  for (double t_scan = 0.0; t_scan + lidar.period <= o.duration; t_scan += lidar.period) {
    if (in_gap(t_scan)) continue;
    const auto pts = test::SimulateScan(scene, pose, o.T_imu_lidar, t_scan, lidar, &rng);
    const double t_end = pts.back().t;
    // IMU up to (and a little past) the scan end arrives before the scan is processed.
    while (t_imu <= t_scan + lidar.period + o.imu_lead_s + 1e-9) {
      ImuSample s = test::ImuFromPose(pose, t_imu);
      s.angular_velocity += gyro_bias + 0.002 * Eigen::Vector3d(n(rng), n(rng), n(rng));
      s.linear_acceleration += o.acc_bias + 0.02 * Eigen::Vector3d(n(rng), n(rng), n(rng));
      s.linear_acceleration /= o.acc_unit;
      const bool imu_dropped = o.imu_gap_length > 0.0 && t_imu >= o.imu_gap_begin &&
                               t_imu < o.imu_gap_begin + o.imu_gap_length;
      if (imu_dropped && o.imu_gap_invalid) {
        s.linear_acceleration.setConstant(std::numeric_limits<double>::quiet_NaN());
        lio.AddImu(s);
      } else if (!in_gap(t_imu) && !o.no_imu && !imu_dropped && t_imu >= o.imu_begin) {
        lio.AddImu(s);
      }
      t_imu += imu_dt;
    }
    const test::CloudBuffer cloud = test::MakeCloud(pts, t_scan, t_end, o.enc);
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

// The largest error of one step's translation (consecutive poses, each in its predecessor's
// frame): a pose jump shows here whatever the world frame.
double MaxStepError(const RunOutput& run) {
  double max_jump = 0.0;
  for (size_t i = 1; i < run.est.size(); ++i) {
    const Eigen::Isometry3d d_est = run.est[i - 1].T.inverse() * run.est[i].T;
    const Eigen::Isometry3d d_gt = run.gt[i - 1].T.inverse() * run.gt[i].T;
    max_jump = std::max(max_jump, (d_est.translation() - d_gt.translation()).norm());
  }
  return max_jump;
}

void CheckAccuracy(const RunOutput& run, const char* label, const std::string& file_tag,
                   double max_ape_share = 0.005, bool world_is_gravity_true = true) {
  ASSERT_GT(run.est.size(), 100u);
  // Kept for inspection with ppf_eval / evo: <TempDir>/ppf_e2e_<tag>_{gt,est}.tum
  const std::string base = ::testing::TempDir() + "ppf_e2e_" + file_tag;
  EXPECT_TRUE(WriteTum(base + "_gt.tum", run.gt));
  EXPECT_TRUE(WriteTum(base + "_est.tum", run.est));
  std::printf("[%s] trajectories: %s_{gt,est}.tum\n", label, base.c_str());
  size_t ok = 0, degenerate = 0, other = 0;
  double max_total_ms = 0.0;
  StageTimings sum;
  for (const ScanResult& r : run.results) {
    sum.preprocess += r.timings.preprocess;
    sum.deskew += r.timings.deskew;
    sum.downsample += r.timings.downsample;
    sum.residuals += r.timings.residuals;
    sum.update += r.timings.update;
    sum.map_insert += r.timings.map_insert;
    sum.total += r.timings.total;
    if (r.status == Status::kOk) ++ok;
    else if (r.status == Status::kDegenerate) ++degenerate;
    else if (r.status != Status::kInitializing) ++other;
    max_total_ms = std::max(max_total_ms, r.timings.total);
  }
  EXPECT_EQ(other, 0u);
  EXPECT_GE(ok, run.est.size() - 2);

  EvalOptions eo;
  eo.align = Alignment::kSE3;
  const EvalResult ape = ComputeApe(run.gt, run.est, eo);
  ASSERT_TRUE(ape.ok) << ape.error;
  eo.align = Alignment::kNone;
  const EvalResult ape_raw = ComputeApe(run.gt, run.est, eo);
  eo.delta = 10;
  const EvalResult rpe = ComputeRpe(run.gt, run.est, eo);
  const double length = PathLength(run.gt);
  std::printf(
      "[%s] scans %zu (ok %zu, degenerate %zu), path %.2f m, APE(se3) rmse %.4f m mean %.4f "
      "max %.4f = %.3f%% of path; APE(none) rmse %.4f max %.4f; RPE(10 frames) rmse %.4f m; "
      "max scan time %.1f ms; final map %zu points\n",
      label, run.est.size(), ok, degenerate, length, ape.stats.rmse, ape.stats.mean,
      ape.stats.max, 100.0 * ape.stats.rmse / length, ape_raw.stats.rmse, ape_raw.stats.max,
      rpe.stats.rmse, max_total_ms, run.results.back().map_size);
  const double n = static_cast<double>(run.results.size());
  std::printf("[%s] mean ms: preprocess %.2f deskew %.2f downsample %.2f residuals %.2f update %.2f "
              "map %.2f total %.2f\n", label, sum.preprocess / n, sum.deskew / n,
              sum.downsample / n, sum.residuals / n, sum.update / n, sum.map_insert / n,
              sum.total / n);
  EXPECT_GT(length, 10.0);
  EXPECT_LT(ape.stats.rmse, max_ape_share * length);
  // The world frame itself is right (gravity, yaw 0).
  if (world_is_gravity_true) {
    EXPECT_LT(ape_raw.stats.max, 0.01 * length);
  }
}

TEST(EndToEnd, VelodyneStyleTimeInRoom) {
  RunOptions o;  // "time" float32 seconds from the scan start stamp
  Config config;
  const RunOutput run = Simulate(o, config);
  CheckAccuracy(run, "velodyne time f32, m/s^2", "velodyne");
  // Every scan after the map exists reports its stage timings and counts.
  const ScanResult& last = run.results.back();
  EXPECT_EQ(last.status, Status::kOk) << last.reason;
  EXPECT_GT(last.knn_residuals, 100u);
  EXPECT_EQ(last.scattered_points, last.downsampled_points);  // kKnn: every point is scattered
  EXPECT_GT(last.map_size, 1000u);
  EXPECT_GT(last.timings.total, 0.0);
  EXPECT_NEAR(last.gravity_map.norm(), 9.81, 0.05);
}

// An accelerometer bias tilts the "up" found at rest (a static accelerometer cannot tell bias from
// tilt). Once the yawing motion separates them, the estimated gravity must come right: the
// reported world is gravity-true again, not the initialization's tilted one.
TEST(EndToEnd, GravityComesRightDespiteAccelerometerBias) {
  RunOptions o;
  o.duration = 20.0;
  o.acc_bias = Eigen::Vector3d(0.08, -0.06, 0.0);  // 0.58 deg of tilt at rest
  Config config;
  const RunOutput run = Simulate(o, config);
  ASSERT_GT(run.est.size(), 150u);
  EvalOptions eo;
  eo.tilt_after_s = 12.0;
  const GravityMetrics g = ComputeGravityMetrics(run.gt, run.est, eo);
  ASSERT_TRUE(g.ok);
  std::printf("[gravity] tilt first %.3f deg, after 12 s: median %.3f max %.3f deg\n",
              g.tilt_deg.front(), g.tilt.median, g.tilt.max);
  EXPECT_GT(g.tilt_deg.front(), 0.45);  // the bias really tilts the start
  // Gravity held fixed in the start frame (the earlier filter), the tilt only grew here: 1.02 deg
  // after 12 s. The small room's map still drifts a little in tilt itself, hence not ~0.
  EXPECT_LT(g.tilt.max, 0.35);
  const ScanResult& last = run.results.back();
  // The reported world is the map frame turned by the estimated gravity's lean, which the
  // accelerometer bias explains: both came most of the way from where initialization left them.
  const double world_map_deg =
      Eigen::AngleAxisd(last.T_world_map.linear()).angle() * 180.0 / M_PI;
  EXPECT_GT(world_map_deg, 0.3);
  EXPECT_LT((last.acc_bias - o.acc_bias).head<2>().norm(), 0.05);  // 0.1 at initialization
}

// No IMU at all: the constant-velocity model predicts and de-skews, the first scan
// builds the map, the world is the first scan's LiDAR frame (not gravity-aligned, hence only the
// SE(3)-aligned APE). Bound: 1 % of the path. Both registration modes.
TEST(EndToEnd, LidarOnlyWithoutImu) {
  for (const Mode mode : {Mode::kKnn, Mode::kPpf}) {
    RunOptions o;
    o.no_imu = true;
    Config config;
    config.mode = mode;
    const RunOutput run = Simulate(o, config);
    const char* label = mode == Mode::kPpf ? "LiDAR-only ppf" : "LiDAR-only knn";
    CheckAccuracy(run, label, mode == Mode::kPpf ? "lidar_only_ppf" : "lidar_only_knn", 0.01,
                  /*world_is_gravity_true=*/false);
    size_t lidar_only_notes = 0, extra_guesses = 0;
    std::vector<double> fits;
    for (const ScanResult& r : run.results) {
      fits.push_back(r.fit);
      if (r.guesses_tried > 1) ++extra_guesses;
      EXPECT_TRUE(r.pose_valid) << r.reason;  // no scan waits for an IMU initialization
      if (r.reason.find("LiDAR-only") != std::string::npos) ++lidar_only_notes;
    }
    EXPECT_EQ(lidar_only_notes, 1u);  // the first scan says so
    std::sort(fits.begin(), fits.end());
    std::printf("[%s] fit median %.2f min %.2f; scans that needed extra guesses: %zu\n", label,
                fits[fits.size() / 2], fits[1], extra_guesses);
    // The first scan's LiDAR frame is the world.
    const Eigen::Isometry3d first_lidar = run.results.front().T_world_lidar;
    EXPECT_LT(first_lidar.translation().norm(), 1e-9);
    EXPECT_LT(Eigen::AngleAxisd(first_lidar.linear()).angle(), 1e-9);
  }
}

// imu.mode auto: scans without IMU wait imu.auto_wait, then run LiDAR-only (none lost).
TEST(EndToEnd, AutoModeFallsBackToLidarOnlyWithoutImu) {
  RunOptions o;
  o.no_imu = true;
  o.duration = 4.0;
  Config config;
  ASSERT_EQ(config.imu.mode, ImuMode::kAuto);
  const RunOutput run = Simulate(o, config);
  ASSERT_GE(run.results.size(), 39u);  // 4 s of 0.1 s scans
  for (const ScanResult& r : run.results) {
    EXPECT_TRUE(r.pose_valid) << r.reason;
    EXPECT_TRUE(r.lidar_only) << r.reason;
  }
}

// imu.mode auto decided LiDAR-only (no IMU with the first 2 s of scans), then the IMU driver
// starts at 4 s: LIO takes over in the same world once the moving-start window has estimated
// gravity from the LiDAR-only poses. No reset, no jump, a pose for every scan, gravity in the
// LiDAR-only world right, and the run as accurate as a LiDAR-only one. Also with the core 1 s
// behind the IMU stream (the ASan node in CI): the scans that began before the first sample stay
// out of the window; failing on them would start the window again and delay LIO.
class LateImu : public ::testing::TestWithParam<double> {};

TEST_P(LateImu, ImuStartingAfterALidarOnlyStartTakesOverWithoutJump) {
  RunOptions o;
  o.duration = 14.0;
  o.imu_begin = 4.0;
  o.imu_lead_s = GetParam();
  const RunOutput run = Simulate(o, Config());
  size_t lidar_only = 0, started = 0;
  double t_started = 0.0;
  for (const ScanResult& r : run.results) {
    EXPECT_NE(r.status, Status::kReset) << r.reason;
    EXPECT_TRUE(r.pose_valid) << r.reason;
    EXPECT_FALSE(r.imu_lost) << r.reason;
    if (r.lio_started_late) {
      ++started;
      t_started = r.stamp_s;
    }
    // LiDAR-only until LIO starts, LIO after.
    EXPECT_EQ(r.lidar_only, started == 0 && !r.lio_started_late) << r.stamp_s << " " << r.reason;
    lidar_only += r.lidar_only;
  }
  ASSERT_EQ(started, 1u);
  // The window: 1.5 s of scans after the first sample (and the scan in flight).
  EXPECT_GT(t_started, 5.4);
  EXPECT_LT(t_started, 6.2);
  EXPECT_GE(lidar_only, 50u);
  const double max_jump = MaxStepError(run);
  // Gravity in the LiDAR-only world: the true one seen through the estimated orientation.
  const ScanResult& last = run.results.back();
  const Eigen::Matrix3d R_world_gtworld = run.est.back().T.linear() *
                                          run.gt.back().T.linear().transpose();
  const Eigen::Vector3d g_true = R_world_gtworld * Eigen::Vector3d(0.0, 0.0, -1.0);
  const double tilt_deg =
      std::acos(std::clamp(last.gravity_map.normalized().dot(g_true), -1.0, 1.0)) * 180.0 / M_PI;
  std::printf("[late IMU] LIO from t=%.2f s, %zu scans LiDAR-only, max step error %.4f m, "
              "gravity %.3f deg off at the end\n",
              t_started, lidar_only, max_jump, tilt_deg);
  EXPECT_LT(max_jump, 0.05);
  EXPECT_LT(tilt_deg, 0.5);
  EXPECT_TRUE(last.T_world_map.isApprox(Eigen::Isometry3d::Identity()));
  CheckAccuracy(run, "IMU from 4 s after a LiDAR-only start", "late_imu", 0.01, false);
}

INSTANTIATE_TEST_SUITE_P(EndToEnd, LateImu, ::testing::Values(0.0, 1.0));

TEST(EndToEnd, OusterStyleTimeImuInGStampAtEnd) {
  RunOptions o;
  o.enc.name = "t";
  o.enc.type = FieldType::kUint32;
  o.enc.unit_s = 1e-9;
  o.enc.stamp_at_end = true;
  o.enc.relative_to_end = false;  // offsets from the first point, header at the end
  o.acc_unit = 9.80665;
  Config config;
  config.time.stamp = StampPosition::kEnd;  // not detectable from >= 0 offsets
  const RunOutput run = Simulate(o, config);
  CheckAccuracy(run, "ouster t u32 ns, stamp at end, IMU in g", "ouster");
}

// Both streams silent for 2 s while the robot moves (a network link down between driver and
// node): the gap is bridged and the trajectory keeps the accuracy bound on both sides of it.
// A reset instead would need a static initialization a moving robot never gives again: no pose
// after the gap at all (a gap beyond the bridge: GapLongerThanTheBridgeReanchorsWithoutReset).
TEST(EndToEnd, TwoSecondGapWhileMovingIsBridged) {
  RunOptions o;
  o.duration = 14.0;  // as many poses as the runs without a gap
  o.gap_begin = 6.0;
  o.gap_length = 2.0;
  const RunOutput run = Simulate(o, Config());
  size_t bridged = 0, after_gap = 0;
  for (const ScanResult& r : run.results) {
    EXPECT_NE(r.status, Status::kReset) << r.reason;
    if (r.imu_gap_s > 0.0) {
      ++bridged;
      EXPECT_NEAR(r.imu_gap_s, 2.0, 0.02);
      EXPECT_NE(r.reason.find("bridged"), std::string::npos) << r.reason;
    }
    if (r.pose_valid && r.stamp_s > o.gap_begin + o.gap_length) ++after_gap;
  }
  EXPECT_EQ(bridged, 1u);
  EXPECT_GE(after_gap, 58u);  // 6 s of scans at 10 Hz after the gap
  CheckAccuracy(run, "2 s gap while moving, bridged", "gap2s");
}

// Beyond imu.max_gap_bridge the filter is not reset (a moving robot would wait for the moving
// start): the first scan after such a gap is registered LiDAR-only (the filter's motion
// continued by the constant-velocity model, several guesses) and LIO re-anchors there: no reset,
// a pose for every scan after the gap, the accuracy bound kept.
TEST(EndToEnd, GapLongerThanTheBridgeReanchorsWithoutReset) {
  RunOptions o;
  o.duration = 14.0;
  o.gap_begin = 6.0;
  o.gap_length = 2.0;
  Config config;
  config.imu.max_gap_bridge_s = 1.5;
  const RunOutput run = Simulate(o, config);
  size_t lost = 0, resumed = 0, after_gap = 0;
  for (const ScanResult& r : run.results) {
    EXPECT_NE(r.status, Status::kReset) << r.reason;
    lost += r.imu_lost;
    if (r.imu_gap_s > 0.0) {
      ++resumed;
      EXPECT_NEAR(r.imu_gap_s, 2.0, 0.02);
      EXPECT_NE(r.reason.find("LIO resumed"), std::string::npos) << r.reason;
      // Not bridged: the scans across it were LiDAR-only, and the result must not say otherwise.
      EXPECT_EQ(r.reason.find("bridged"), std::string::npos) << r.reason;
      EXPECT_TRUE(r.lio_resumed);
    }
    if (r.pose_valid && r.stamp_s > o.gap_begin + o.gap_length) ++after_gap;
  }
  EXPECT_GE(lost, 1u);
  EXPECT_LE(lost, 2u);
  EXPECT_EQ(resumed, 1u);
  EXPECT_GE(after_gap, 58u);  // 6 s of scans at 10 Hz after the gap
  CheckAccuracy(run, "2 s gap > imu.max_gap_bridge, re-anchored", "gap2s_reanchored");
}

// The IMU stops for 3 s while the scans go on: LiDAR-only over the dropout, LIO again after it,
// within the accuracy of the same run without the dropout plus 50 %.
TEST(EndToEnd, ImuDropoutOfThreeSecondsContinuesLidarOnly) {
  RunOptions o;
  o.duration = 14.0;
  const RunOutput plain = Simulate(o, Config());
  o.imu_gap_begin = 6.0;
  o.imu_gap_length = 3.0;
  const RunOutput run = Simulate(o, Config());
  size_t lost = 0, resumed = 0;
  for (const ScanResult& r : run.results) {
    EXPECT_NE(r.status, Status::kReset) << r.reason;
    EXPECT_TRUE(r.pose_valid || r.status == Status::kInitializing) << r.reason;
    lost += r.imu_lost;
    resumed += r.imu_gap_s > 0.0;
  }
  const double max_jump = MaxStepError(run);
  EXPECT_GE(lost, 20u);
  EXPECT_EQ(resumed, 1u);
  EvalOptions eo;
  eo.align = Alignment::kSE3;
  const EvalResult ape_plain = ComputeApe(plain.gt, plain.est, eo);
  const EvalResult ape = ComputeApe(run.gt, run.est, eo);
  ASSERT_TRUE(ape_plain.ok && ape.ok);
  std::printf("[3 s IMU dropout] %zu scans LiDAR-only; APE rmse %.4f m vs %.4f m without; max "
              "pose jump %.4f m\n",
              lost, ape.stats.rmse, ape_plain.stats.rmse, max_jump);
  EXPECT_LE(max_jump, 0.2);
  EXPECT_LE(ape.stats.rmse, 1.5 * ape_plain.stats.rmse);
}

// An IMU that goes on sending, but only invalid (NaN) samples, is lost too: the same fallback.
TEST(EndToEnd, ImuSendingOnlyInvalidSamplesFallsBackToLidarOnly) {
  RunOptions o;
  o.duration = 10.0;
  o.imu_gap_begin = 5.0;
  o.imu_gap_length = 2.0;
  o.imu_gap_invalid = true;
  const RunOutput run = Simulate(o, Config());
  size_t lost = 0, resumed = 0, after = 0;
  for (const ScanResult& r : run.results) {
    EXPECT_NE(r.status, Status::kReset) << r.reason;
    lost += r.imu_lost;
    resumed += r.imu_gap_s > 0.0;
    if (r.stamp_s > 7.5) {
      EXPECT_FALSE(r.imu_lost) << r.stamp_s;
      after += r.pose_valid;
    }
  }
  EXPECT_GE(lost, 10u);
  EXPECT_EQ(resumed, 1u);
  EXPECT_GE(after, 20u);
}

}  // namespace
}  // namespace ppf
