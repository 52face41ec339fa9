// Facade behaviour: statuses (initializing, rejected, reset), counts, and kPpf's labels deciding
// residual sources and map insertion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "ppf_core/lio_ppf.hpp"
#include "synthetic.hpp"

namespace ppf {
namespace {

ImuSample Still(double t) {
  ImuSample s;
  s.stamp_s = t;
  s.linear_acceleration = Eigen::Vector3d(0, 0, 9.81);
  return s;
}

test::CloudBuffer StillScan(double t0) {
  test::LidarModel lidar;
  lidar.azimuth_steps = 360;
  const test::PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  const auto pts = test::SimulateScan(test::MakeRoomScene(), still, Eigen::Isometry3d::Identity(),
                                      t0, lidar);
  return test::MakeCloud(pts, t0, pts.back().t, test::TimeEncoding());
}

void FeedStill(LioPpf* lio, double from, double to) {
  for (double t = from; t <= to + 1e-9; t += 0.005) lio->AddImu(Still(t));
}

TEST(LioPpf, InitializingUntilOneSecondOfStaticImu) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 0.5);
  const test::CloudBuffer scan = StillScan(0.4);
  ScanResult r = lio.ProcessScan(scan.view);
  EXPECT_EQ(r.status, Status::kInitializing);
  EXPECT_FALSE(r.pose_valid);
  EXPECT_FALSE(r.reason.empty());
  FeedStill(&lio, 0.505, 1.6);
  EXPECT_TRUE(lio.initialized());
  const test::CloudBuffer s1 = StillScan(1.4);
  r = lio.ProcessScan(s1.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
  EXPECT_NE(r.reason.find("map initialized"), std::string::npos);
  EXPECT_GT(lio.map_stats().points, 0u);
  FeedStill(&lio, 1.605, 1.7);
  const test::CloudBuffer s2 = StillScan(1.5);
  r = lio.ProcessScan(s2.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
  EXPECT_LT(r.T_world_imu.translation().norm(), 0.01);
  EXPECT_GT(r.knn_residuals, 100u);
}

TEST(LioPpf, MotionDuringInitIsReported) {
  LioPpf lio;
  for (double t = 0.0; t <= 1.5; t += 0.005) {
    ImuSample s = Still(t);
    s.linear_acceleration.x() = 3.0 * std::sin(15.0 * t);
    lio.AddImu(s);
  }
  const test::CloudBuffer scan = StillScan(1.3);
  const ScanResult r = lio.ProcessScan(scan.view);
  EXPECT_EQ(r.status, Status::kInitializing);
  EXPECT_NE(r.reason.find("motion"), std::string::npos) << r.reason;
}

TEST(LioPpf, MalformedCloudIsRejectedAndChangesNothing) {
  std::vector<std::string> logs;
  Config config;
  config.log = [&](LogLevel, const std::string& m) { logs.push_back(m); };
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.2);
  const test::CloudBuffer good = StillScan(1.0);
  CloudView bad = good.view;
  bad.point_step = 6;
  ScanResult r = lio.ProcessScan(bad);
  EXPECT_EQ(r.status, Status::kRejected);
  EXPECT_NE(r.reason.find("point_step"), std::string::npos) << r.reason;
  bad = good.view;
  bad.size /= 2;
  r = lio.ProcessScan(bad);
  EXPECT_EQ(r.status, Status::kRejected);
  EXPECT_NE(r.reason.find("size mismatch"), std::string::npos) << r.reason;
  EXPECT_EQ(lio.map_stats().points, 0u);
  EXPECT_FALSE(logs.empty());
  // A good scan afterwards works normally.
  r = lio.ProcessScan(good.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
}

TEST(LioPpf, NanPointsAreCounted) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.2);
  test::LidarModel lidar;
  lidar.azimuth_steps = 360;
  const test::PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  auto pts = test::SimulateScan(test::MakeRoomScene(), still, Eigen::Isometry3d::Identity(), 1.0,
                                lidar);
  for (size_t i = 0; i < 25; ++i) pts[i * 7].p.y() = std::nanf("");
  const test::CloudBuffer c = test::MakeCloud(pts, 1.0, pts.back().t, test::TimeEncoding());
  const ScanResult r = lio.ProcessScan(c.view);
  EXPECT_EQ(r.dropped_nan, 25u);
  EXPECT_EQ(r.input_points, pts.size());
  EXPECT_EQ(r.status, Status::kOk);
}

// A corrupt point time neither holds the scan back (waiting for IMU coverage 1e6 s ahead) nor
// resets the filter (time "going backwards"): the point is dropped and counted; a scan whose times
// are mostly corrupt is skipped with its reason, and the next scan goes on.
TEST(LioPpf, ImplausiblePointTimesAreDroppedNotTrusted) {
  std::vector<std::string> warns;
  Config config;
  config.log = [&](LogLevel level, const std::string& m) {
    if (level == LogLevel::kWarn) warns.push_back(m);
  };
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.45);
  const test::CloudBuffer s1 = StillScan(1.0);
  ASSERT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);

  test::LidarModel lidar;
  lidar.azimuth_steps = 360;
  const test::PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  const auto scan_at = [&](double t0) {
    return test::SimulateScan(test::MakeRoomScene(), still, Eigen::Isometry3d::Identity(), t0,
                              lidar);
  };
  std::vector<test::SimPoint> pts = scan_at(1.1);
  const double t_last = pts.back().t;
  pts[3].t += 1e6;
  pts[4].t -= 100.0;
  const test::CloudBuffer glitch = test::MakeCloud(pts, 1.1, t_last, test::TimeEncoding());
  lio.AddScan(glitch.view);
  std::vector<ScanResult> rs = lio.Process();  // no flush: covered by the IMU up to t_last
  ASSERT_EQ(rs.size(), 1u);
  EXPECT_EQ(rs[0].status, Status::kOk) << rs[0].reason;
  EXPECT_EQ(rs[0].points_bad_time, 2u);
  EXPECT_NEAR(rs[0].stamp_s, t_last, 1e-6);
  EXPECT_NEAR(rs[0].scan_begin_s, 1.1, 1e-6);
  const size_t map_points = lio.map_stats().points;

  pts = scan_at(1.2);
  const double t_last2 = pts.back().t;
  for (test::SimPoint& p : pts) p.t -= 100.0;
  const test::CloudBuffer early = test::MakeCloud(pts, 1.2, t_last2, test::TimeEncoding());
  lio.AddScan(early.view);
  rs = lio.Process();
  ASSERT_EQ(rs.size(), 1u);
  EXPECT_EQ(rs[0].status, Status::kRejected);
  EXPECT_NE(rs[0].reason.find("sweep window"), std::string::npos) << rs[0].reason;
  EXPECT_EQ(rs[0].points_bad_time, pts.size());
  EXPECT_TRUE(lio.initialized());
  EXPECT_EQ(lio.map_stats().points, map_points);

  const test::CloudBuffer s3 = StillScan(1.3);
  lio.AddScan(s3.view);
  rs = lio.Process();
  ASSERT_EQ(rs.size(), 1u);
  EXPECT_EQ(rs[0].status, Status::kOk) << rs[0].reason;
  EXPECT_EQ(rs[0].points_bad_time, 0u);
  // One line for both scans (rate limited), none about a reset.
  size_t window_lines = 0;
  for (const std::string& w : warns) {
    window_lines += w.find("sweep window") != std::string::npos ? 1 : 0;
    EXPECT_EQ(w.find("reset"), std::string::npos) << w;
  }
  EXPECT_EQ(window_lines, 1u);
}

size_t CountContaining(const std::vector<std::string>& lines, const std::string& what) {
  size_t n = 0;
  for (const std::string& l : lines) n += l.find(what) != std::string::npos ? 1 : 0;
  return n;
}

// Each stamp of 0.3 s comes twice, a wrong copy (acc +5 m/s^2, gyro +1 rad/s) before or after
// the right one: the copy that fits the samples either side is integrated, whatever the arrival
// order, and the conflicts are counted and named.
TEST(LioPpf, ConflictingImuDuplicatesKeepTheConsistentCopy) {
  std::vector<std::string> warns;
  Config config;
  config.log = [&](LogLevel level, const std::string& m) {
    if (level == LogLevel::kWarn) warns.push_back(m);
  };
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.2);
  const test::CloudBuffer s1 = StillScan(1.0);
  ASSERT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);
  size_t stamps = 0;
  for (double t = 1.205; t <= 1.5; t += 0.005, ++stamps) {
    ImuSample bad = Still(t);
    bad.linear_acceleration.x() += 5.0;
    bad.angular_velocity.z() += 1.0;
    if (stamps % 2 == 0) lio.AddImu(bad);
    lio.AddImu(Still(t));
    lio.AddImu(Still(t));  // a plain redelivery of the right copy: not a conflict
    if (stamps % 2 == 1) lio.AddImu(bad);
  }
  lio.AddImu(Still(1.5025));  // completes the stamp after the last conflict ...
  lio.AddImu(Still(1.505));   // ... which is then decided
  const test::CloudBuffer s2 = StillScan(1.3);
  const ScanResult r = lio.ProcessScan(s2.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
  EXPECT_EQ(r.imu_conflicts, stamps);
  EXPECT_EQ(r.imu_conflicts_unresolved, 0u);
  EXPECT_LT(r.T_world_imu.translation().norm(), 0.01);
  EXPECT_LT(r.velocity_world.norm(), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(r.T_world_imu.linear()).angle(), 1e-3);
  const InputStats st = lio.input_stats();
  EXPECT_EQ(st.imu_conflicts, stamps);
  EXPECT_EQ(st.imu_duplicates, stamps);  // the redeliveries of the right copy
  EXPECT_EQ(CountContaining(warns, "IMU samples in conflict"), 1u);  // rate limited: 0.3 s
}

// Two copies equally far from their neighbours: neither is integrated.
TEST(LioPpf, ImuConflictWithoutAConsistentCopyKeepsNeither) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.2);
  const test::CloudBuffer s1 = StillScan(1.0);
  ASSERT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);
  ImuSample up = Still(1.205), down = Still(1.205);
  up.linear_acceleration.x() += 3.0;
  down.linear_acceleration.x() -= 3.0;
  lio.AddImu(up);
  lio.AddImu(down);
  FeedStill(&lio, 1.21, 1.45);
  const test::CloudBuffer s2 = StillScan(1.3);
  const ScanResult r = lio.ProcessScan(s2.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
  EXPECT_EQ(r.imu_conflicts, 1u);
  EXPECT_EQ(r.imu_conflicts_unresolved, 1u);
  EXPECT_LT(r.velocity_world.norm(), 0.01);
}

// Gaps the propagation integrates across without a word (below imu.max_gap) are still counted
// and named, each once; a short one (0.05 s) is not.
TEST(LioPpf, EveryImuGapOverMaxGapWarnIsCountedAndNamed) {
  std::vector<std::string> warns;
  Config config;
  config.log = [&](LogLevel level, const std::string& m) {
    if (level == LogLevel::kWarn) warns.push_back(m);
  };
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.2);
  const test::CloudBuffer s1 = StillScan(1.0);
  ASSERT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);
  FeedStill(&lio, 1.205, 1.3);
  FeedStill(&lio, 1.5, 1.6);   // 0.2 s silent
  FeedStill(&lio, 1.65, 2.6);  // 0.05 s: not a gap to report
  FeedStill(&lio, 3.0, 3.2);   // 0.4 s silent (< imu.max_gap 0.5 s: integrated across)
  const test::CloudBuffer s2 = StillScan(3.05);
  const ScanResult r = lio.ProcessScan(s2.view);
  EXPECT_EQ(r.status, Status::kOk) << r.reason;
  EXPECT_EQ(r.imu_gaps, 2u);
  EXPECT_NEAR(r.imu_gap_longest_s, 0.4, 1e-3);
  EXPECT_EQ(lio.input_stats().imu_gaps, 2u);
  EXPECT_EQ(CountContaining(warns, "imu.max_gap_warn"), 2u);
  // The next result reports only what came after it.
  FeedStill(&lio, 3.205, 3.3);
  const test::CloudBuffer s3 = StillScan(3.15);
  EXPECT_EQ(lio.ProcessScan(s3.view).imu_gaps, 0u);
}

// The IMU clock 5 s behind the LiDAR's, both streams live, the IMU shaking (no static start): the
// moving start waited for IMU coverage that never comes (kInitializing for good). Now the offset
// is named once, the scans are registered LiDAR-only with valid poses, and when the clocks agree
// again the IMU is taken up without a reset.
TEST(LioPpf, ImuClockSecondsBehindRunsLidarOnlyUntilTheClocksAgree) {
  std::vector<std::string> warns, infos;
  Config config;
  config.log = [&](LogLevel level, const std::string& m) {
    (level == LogLevel::kWarn ? warns : infos).push_back(m);
  };
  LioPpf lio(config);
  double t_imu = 3.0;
  std::vector<ScanResult> rs;
  const auto step = [&](double t_scan, double imu_behind_s) {
    t_imu = std::max(t_imu, t_scan - imu_behind_s);
    for (; t_imu <= t_scan + 0.1 - imu_behind_s + 1e-9; t_imu += 0.005) {
      ImuSample s = Still(t_imu);
      s.linear_acceleration.x() = 3.0 * std::sin(15.0 * t_imu);
      lio.AddImu(s);
    }
    const test::CloudBuffer c = StillScan(t_scan);
    lio.AddScan(c.view);
    for (ScanResult& r : lio.Process()) rs.push_back(std::move(r));
  };
  int k = 0;
  for (; k < 25; ++k) step(9.0 + 0.1 * k, 5.0);
  ASSERT_EQ(rs.size(), 25u);
  EXPECT_EQ(CountContaining(warns, "s behind the LiDAR's"), 1u);
  for (int i = 12; i < 25; ++i) {
    EXPECT_TRUE(rs[i].pose_valid) << i << ": " << rs[i].reason;
    EXPECT_NEAR(rs[i].imu_clock_offset_s, 5.0, 0.15) << i;
    EXPECT_TRUE(rs[i].lidar_only) << i;
    EXPECT_LT(rs[i].T_world_lidar.translation().norm(), 0.02) << i;
  }
  EXPECT_GT(lio.input_stats().imu_clock_offset_dropped, 0u);
  // The IMU clock catches up: after kClockOffsetScans agreeing scans the IMU is used again.
  for (; k < 40; ++k) step(9.0 + 0.1 * k, 0.0);
  ASSERT_EQ(rs.size(), 40u);
  EXPECT_EQ(CountContaining(infos, "clocks agree again"), 1u);
  for (int i = 25; i < 40; ++i) {
    EXPECT_NE(rs[i].status, Status::kReset) << i << ": " << rs[i].reason;
    EXPECT_TRUE(rs[i].pose_valid) << i << ": " << rs[i].reason;
  }
  EXPECT_EQ(rs.back().imu_clock_offset_s, 0.0);
}

TEST(LioPpf, TimeGoingBackwardsResets) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.2);
  const test::CloudBuffer s1 = StillScan(1.0);
  EXPECT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);
  FeedStill(&lio, 0.0, 0.2);  // bag loop: IMU jumps back 1.2 s
  const std::vector<ScanResult> rs = lio.Process(true);
  ASSERT_FALSE(rs.empty());
  EXPECT_EQ(rs.front().status, Status::kReset);
  EXPECT_NE(rs.front().reason.find("backwards"), std::string::npos) << rs.front().reason;
  EXPECT_FALSE(lio.initialized());
  EXPECT_EQ(lio.map_stats().points, 0u);
  // Recovers: a new static second initializes again.
  FeedStill(&lio, 0.205, 1.5);
  EXPECT_TRUE(lio.initialized());
}

// Results name their scan by the id AddScan returned; a reset the IMU stream causes is a notice
// with id 0, so a caller matching results to its own per-scan records never mismatches them.
TEST(LioPpf, ResultsCarryTheirInputIdAndResetNoticesNone) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.3);
  const test::CloudBuffer s1 = StillScan(1.0), s2 = StillScan(1.1), bad_src = StillScan(1.2);
  CloudView bad = bad_src.view;
  bad.point_step = 6;
  EXPECT_EQ(lio.AddScan(s1.view), 1u);
  EXPECT_EQ(lio.AddScan(bad), 2u);
  EXPECT_EQ(lio.AddScan(s2.view), 3u);
  std::vector<ScanResult> rs = lio.Process();
  ASSERT_EQ(rs.size(), 3u);
  EXPECT_EQ(rs[0].input_id, 1u);
  EXPECT_EQ(rs[1].input_id, 2u);
  EXPECT_EQ(rs[1].status, Status::kRejected);
  EXPECT_EQ(rs[2].input_id, 3u);
  FeedStill(&lio, 0.0, 0.2);  // IMU jumps back: the core resets
  const test::CloudBuffer s3 = StillScan(0.1);
  EXPECT_EQ(lio.AddScan(s3.view), 4u);
  rs = lio.Process(true);
  ASSERT_EQ(rs.size(), 2u);
  EXPECT_EQ(rs[0].status, Status::kReset);
  EXPECT_EQ(rs[0].input_id, 0u);
  EXPECT_EQ(rs[1].input_id, 4u);
  lio.Reset();  // ids go on over a reset
  EXPECT_EQ(lio.AddScan(s1.view), 5u);
}

// The odometry twist's rate comes from the core: the gyro sample at the scan end, bias removed;
// the registered points on request are the downsampled, de-skewed scan.
TEST(LioPpf, ResultCarriesAngularRateAndDeskewedPointsOnRequest) {
  for (const bool keep : {false, true}) {
    Config config;
    config.output_deskewed_points = keep;
    LioPpf lio(config);
    FeedStill(&lio, 0.0, 1.3);
    const test::CloudBuffer s1 = StillScan(1.0);
    EXPECT_EQ(lio.ProcessScan(s1.view).status, Status::kOk);
    // A slow yaw rate up to 1.45 s, a fast one after it (the scan below ends before that).
    const auto rate_at = [](double t) { return t <= 1.45 + 1e-9 ? 0.01 : 0.5; };
    for (int k = 1; k <= 60; ++k) {
      ImuSample s = Still(1.3 + 0.005 * k);
      s.angular_velocity = Eigen::Vector3d(0, 0, rate_at(s.stamp_s));
      lio.AddImu(s);
    }
    const test::CloudBuffer s2 = StillScan(1.32);
    const ScanResult r = lio.ProcessScan(s2.view);
    ASSERT_TRUE(r.pose_valid) << r.reason;
    // The last sample at or before the scan end, not the last one fed (1.6 s, 0.5 rad/s).
    const double t_sample = 1.3 + 0.005 * std::floor((r.stamp_s - 1.3) / 0.005 + 1e-9);
    ASSERT_GT(t_sample, 1.3);
    const Eigen::Vector3d raw(0, 0, rate_at(t_sample));
    EXPECT_LT((r.angular_velocity - (raw - r.gyro_bias)).norm(), 1e-12)
        << r.angular_velocity.transpose() << " at " << r.stamp_s;
    EXPECT_NEAR(r.angular_velocity.z(), 0.01, 0.005);
    if (keep) {
      EXPECT_EQ(r.deskewed_points_lidar.size(), r.downsampled_points);
      EXPECT_GT(r.deskewed_points_lidar.size(), 100u);
      // Registered into the room: every world point lies within its walls (x +-14, y +-10,
      // z -2..4 m) to a few centimetres.
      for (const Eigen::Vector3f& p : r.deskewed_points_lidar) {
        const Eigen::Vector3d w = r.T_world_lidar * p.cast<double>();
        ASSERT_LT(std::abs(w.x()), 14.05) << w.transpose();
        ASSERT_LT(std::abs(w.y()), 10.05) << w.transpose();
        ASSERT_GT(w.z(), -2.05) << w.transpose();
        ASSERT_LT(w.z(), 4.05) << w.transpose();
      }
      // One label per point, and they add up to the result's own counts.
      ASSERT_EQ(r.deskewed_point_labels.size(), r.deskewed_points_lidar.size());
      size_t counts[3] = {0, 0, 0};
      for (const PointLabel l : r.deskewed_point_labels) ++counts[static_cast<int>(l)];
      EXPECT_EQ(counts[static_cast<int>(PointLabel::kScattered)], r.scattered_points);
      EXPECT_EQ(counts[static_cast<int>(PointLabel::kSkeleton)], r.skeleton_points);
      EXPECT_EQ(counts[static_cast<int>(PointLabel::kDiscarded)], r.discarded_points);
    } else {
      EXPECT_TRUE(r.deskewed_points_lidar.empty());
      EXPECT_TRUE(r.deskewed_point_labels.empty());
    }
  }
}

TEST(LioPpf, StalledImuDoesNotHoldScansForever) {
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.3);
  const test::CloudBuffer s1 = StillScan(1.2);
  lio.AddScan(s1.view);
  ASSERT_EQ(lio.Process().size(), 1u);  // covered by the IMU
  const test::CloudBuffer s2 = StillScan(1.3);
  lio.AddScan(s2.view);
  EXPECT_TRUE(lio.Process().empty());  // waits for IMU up to its end
  const test::CloudBuffer s3 = StillScan(2.0);  // IMU silent for 0.7 s > imu.max_gap 0.5 s
  lio.AddScan(s3.view);
  const std::vector<ScanResult> rs = lio.Process();
  ASSERT_EQ(rs.size(), 2u);
  // The scan just past the last sample extrapolates it; the one ending more than
  // imu.loss_timeout after it is registered LiDAR-only (IMU loss fallback).
  EXPECT_NE(rs[0].reason.find("IMU extrapolated"), std::string::npos) << rs[0].reason;
  EXPECT_FALSE(rs[0].imu_lost);
  EXPECT_TRUE(rs[1].imu_lost) << rs[1].reason;
  EXPECT_TRUE(rs[1].pose_valid);
}

TEST(LioPpf, NoTimeFieldFallbackIsReported) {
  Config config;
  config.time.no_time_policy = NoTimePolicy::kNoDeskew;
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.2);
  test::LidarModel lidar;
  lidar.azimuth_steps = 180;
  const test::PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  const auto pts = test::SimulateScan(test::MakeRoomScene(), still, Eigen::Isometry3d::Identity(),
                                      1.0, lidar);
  test::TimeEncoding none;
  none.name = "";
  const test::CloudBuffer c = test::MakeCloud(pts, 1.05, 1.05, none);
  const ScanResult r = lio.ProcessScan(c.view);
  EXPECT_NE(r.reason.find("not de-skewed"), std::string::npos) << r.reason;
  EXPECT_FALSE(lio.time_field_info().present);
}

TEST(LioPpf, CorridorIsReportedDegenerate) {
  // A long corridor whose ends are out of range: nothing constrains motion along x.
  test::Scene corridor;
  corridor.boxes.push_back({Eigen::Vector3d(-300, -2, -1.5), Eigen::Vector3d(300, 2, 2.5), true});
  test::LidarModel lidar;
  lidar.azimuth_steps = 360;
  lidar.max_range = 40.0;
  const test::PoseFn still = [](double) { return Eigen::Isometry3d::Identity(); };
  LioPpf lio;
  FeedStill(&lio, 0.0, 1.25);
  ScanResult r;
  for (double t0 : {1.0, 1.1}) {
    const auto pts =
        test::SimulateScan(corridor, still, Eigen::Isometry3d::Identity(), t0, lidar);
    const test::CloudBuffer c = test::MakeCloud(pts, t0, pts.back().t, test::TimeEncoding());
    r = lio.ProcessScan(c.view);
  }
  EXPECT_EQ(r.status, Status::kDegenerate) << r.reason;
  EXPECT_TRUE(r.pose_valid);
  EXPECT_NE(r.reason.find("translation"), std::string::npos) << r.reason;
  EXPECT_LT(r.eig_translation(0), lio.config().iekf.degeneracy_min_eig_translation);
  EXPECT_LT(r.T_world_imu.translation().norm(), 0.01);  // the IMU (static) keeps x in place
}

// kPpf: the skeleton tracker's labels decide where each point's residual comes from and what
// enters the map (only kScattered points do).
TEST(LioPpf, PpfModeLabelsDecideResidualSourcesAndMapInsertion) {
  Config config;
  config.mode = Mode::kPpf;
  LioPpf lio(config);
  FeedStill(&lio, 0.0, 1.4);
  const test::CloudBuffer s1 = StillScan(1.0);
  ScanResult r = lio.ProcessScan(s1.view);  // map initialization: no split yet
  ASSERT_EQ(r.status, Status::kOk);
  EXPECT_EQ(r.skeleton_points, 0u);
  const test::CloudBuffer s2 = StillScan(1.1);
  r = lio.ProcessScan(s2.view);  // its planes start the window: no skeleton rows yet
  ASSERT_TRUE(r.pose_valid) << r.reason;
  EXPECT_EQ(r.skeleton_residuals, 0u);
  EXPECT_FALSE(r.skeleton_planes.empty());
  const size_t map_before = lio.map_stats().points;
  const test::CloudBuffer s3 = StillScan(1.2);
  r = lio.ProcessScan(s3.view);
  ASSERT_TRUE(r.pose_valid) << r.reason;
  EXPECT_GT(r.skeleton_points, r.downsampled_points / 4) << "the room's walls are skeleton planes";
  EXPECT_GT(r.scattered_points, 0u);
  EXPECT_FALSE(r.skeleton_planes.empty());
  EXPECT_EQ(r.skeleton_points + r.scattered_points + r.discarded_points, r.downsampled_points);
  EXPECT_EQ(r.map_inserted, r.scattered_points);  // only map points enter the map
  EXPECT_GT(r.skeleton_residuals, 0u);
  EXPECT_LE(r.knn_residuals, r.scattered_points);
  EXPECT_LE(lio.map_stats().points, map_before + r.scattered_points);
  EXPECT_LT(r.T_world_lidar.translation().norm(), 0.01);

  Config knn_config;  // kKnn: no split, every point a map point
  LioPpf knn(knn_config);
  FeedStill(&knn, 0.0, 1.3);
  knn.ProcessScan(s1.view);
  r = knn.ProcessScan(s2.view);
  ASSERT_TRUE(r.pose_valid) << r.reason;
  EXPECT_EQ(r.scattered_points, r.downsampled_points);
  EXPECT_EQ(r.skeleton_residuals, 0u);
  EXPECT_TRUE(r.skeleton_planes.empty());
}

}  // namespace
}  // namespace ppf
