// Moving start: sequences whose first scan and IMU sample are already in motion
// (ppf_sim --moving-start) must give odometry within 3 s of the first scan, with gravity right
// from the start: position+yaw-aligned APE (a tilted world shows as error there) within the
// static-start bound of the accuracy study, 0.5 % of the path, over the whole run. Without the
// moving-start initialization the IMU never shows rest and no scan gets a pose.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>

#include "ppf_core/config.hpp"
#include "ppf_sim/imu_simulator.hpp"
#include "ppf_sim/scan_generator.hpp"
#include "ppf_sim/world.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/study.hpp"
#include "ppf_trajectory/evaluation.hpp"
#include "sim_sequence.hpp"

namespace fs = std::filesystem;

namespace {

struct Case {
  std::string name;
  std::string sim_args;
  std::string lidar;  // config preset
  double duration;
  ppf::Mode mode;
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.name; }

class MovingStart : public ::testing::TestWithParam<Case> {};

TEST_P(MovingStart, OdometryWithin3sAndGravityRightFromTheStart) {
  const Case& c = GetParam();
  const std::string bag =
      ppf::tools::test::GenerateSimSequence(c.sim_args, c.duration, " --moving-start");
  ASSERT_TRUE(fs::exists(fs::path(bag) / "groundtruth.tum"));

  ppf::Config config;
  ASSERT_TRUE(ppf::tools::test::LoadPresetAndCalibration(c.lidar, bag, &config));
  config.mode = c.mode;
  std::string moving_log;
  config.log = [&moving_log](ppf::LogLevel level, const std::string& msg) {
    if (level == ppf::LogLevel::kInfo && msg.find("moving start") != std::string::npos) {
      moving_log += msg + "\n";
    }
  };

  const auto run = ppf::tools::RunOffline(bag, config);
  ASSERT_FALSE(run.lidar_only);
  ASSERT_FALSE(run.results.empty());
  ppf::Trajectory gt;
  std::string error;
  ASSERT_TRUE(ppf::ReadTum(bag + "/groundtruth.tum", &gt, &error)) << error;

  // The sequence really starts moving: the ground truth's first second covers metres.
  ASSERT_GE(gt.size(), 2u);
  size_t i1 = 0;
  while (i1 + 1 < gt.size() && gt[i1].stamp_s - gt[0].stamp_s < 1.0) ++i1;
  ASSERT_GT((gt[i1].T.translation() - gt[0].T.translation()).norm(), 0.5);

  const double first_scan = run.results.front().scan_begin_s;
  double first_pose = -1.0;
  size_t resets = 0, after_first = 0, valid_after_first = 0;
  for (const auto& r : run.results) {
    resets += r.status == ppf::Status::kReset;
    if (r.pose_valid && first_pose < 0) first_pose = r.stamp_s;
    if (first_pose >= 0) {
      ++after_first;
      valid_after_first += r.pose_valid;
    }
  }
  EXPECT_EQ(resets, 0u);
  ASSERT_GE(first_pose, 0.0) << "no odometry at all: " << run.results.back().reason;
  EXPECT_LE(first_pose - first_scan, 3.0) << "first odometry too late";
  // Once started, every scan has a pose.
  EXPECT_EQ(valid_after_first, after_first);
  EXPECT_NE(moving_log.find("IMU initialized from a moving start"), std::string::npos)
      << moving_log;

  ppf::EvalOptions eval;
  eval.align = ppf::Alignment::kSE3;
  const auto ape = ppf::ComputeApe(gt, run.trajectory, eval);
  ASSERT_TRUE(ape.ok) << ape.error;
  eval.align = ppf::Alignment::kPosYaw;
  eval.tilt_after_s = 0.0;
  const auto ape_posyaw = ppf::ComputeApe(gt, run.trajectory, eval);
  ASSERT_TRUE(ape_posyaw.ok) << ape_posyaw.error;
  EXPECT_EQ(ape_posyaw.matched, valid_after_first);
  // Path of the scored part only: the poses start at the first odometry.
  const double path = ppf::PathLength(run.trajectory);
  const double percent = 100.0 * ape_posyaw.stats.rmse / std::max(path, 1e-9);
  const ppf::GravityMetrics& g = ape_posyaw.gravity;
  std::cout << "[ MOVING ] " << c.name << ": first odometry " << first_pose - first_scan
            << " s after the first scan; APE SE(3) " << ape.stats.rmse << " m, position+yaw "
            << ape_posyaw.stats.rmse << " m over " << path << " m (" << percent
            << " %); tilt median " << g.tilt.median << " max " << g.tilt.max << " deg\n"
            << moving_log;
  EXPECT_LE(percent, 0.5) << "position+yaw APE " << ape_posyaw.stats.rmse << " m on a " << path
                          << " m path";
}

const ppf::Mode kKnn = ppf::Mode::kKnn;
const ppf::Mode kPpf = ppf::Mode::kPpf;

INSTANTIATE_TEST_SUITE_P(
    Simulated, MovingStart,
    ::testing::Values(Case{"urban_vlp16_knn", "--scene urban --lidar vlp16", "vlp16", 12, kKnn},
                      Case{"urban_vlp16_ppf", "--scene urban --lidar vlp16", "vlp16", 12, kPpf},
                      Case{"handheld_indoor_vlp16_knn",
                           "--scene indoor --lidar vlp16 --motion handheld", "vlp16", 12, kKnn},
                      Case{"handheld_indoor_vlp16_ppf",
                           "--scene indoor --lidar vlp16 --motion handheld", "vlp16", 12, kPpf}),
    [](const ::testing::TestParamInfo<Case>& info) { return info.param.name; });

// KITTI raw layout written from a simulated moving-start drive (an HDL-64E as in KITTI, 100 Hz
// OXTS), imported with the installed ppf_import_kitti as a user would, then run through the
// offline loop. The importer's own assumptions (per-point time from the azimuth of a clockwise
// sweep starting behind the sensor, ground truth from OXTS lat/lon by the devkit's Mercator
// scale) are part of what is tested: they match the simulator's sensor.
std::string KittiStamp(int64_t ns) {
  const std::time_t s = static_cast<std::time_t>(ns / 1000000000LL);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[64];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S", &tm);
  std::ostringstream os;
  os << buf << "." << std::setw(9) << std::setfill('0') << ns % 1000000000LL;
  return os.str();
}

void WriteKittiDrive(const fs::path& date_dir, const fs::path& raw, double duration) {
  using namespace ppf::sim;
  WorldOptions wo;
  wo.scene = "urban";
  wo.duration = duration;
  wo.moving_start = true;
  wo.seed = 1;
  const World world = BuildWorld(wo);
  const int64_t start_ns = 1317042145LL * 1000000000LL;  // 2011-09-26 13:02:25 UTC
  const double rate = 100.0;
  const auto imu = SimulateImu(world.trajectory, rate, duration, ImuNoise(), 1);
  ScanOptions so;
  so.seed = 1;
  so.start_ns = start_ns;
  so.T_imu_lidar = DefaultImuLidarExtrinsic();
  const ScanGenerator gen(world.scene, world.trajectory, GetLidarModel("hdl64"), so);

  fs::create_directories(raw / "velodyne_points" / "data");
  fs::create_directories(raw / "oxts" / "data");
  std::ofstream ts(raw / "velodyne_points" / "timestamps_start.txt");
  std::ofstream te(raw / "velodyne_points" / "timestamps_end.txt");
  std::ofstream tm(raw / "velodyne_points" / "timestamps.txt");
  const int64_t period_ns = static_cast<int64_t>(std::llround(gen.period() * 1e9));
  for (int k = 0; k < gen.NumScans(duration); ++k) {
    const CloudBuffer c = gen.Generate(k);
    const int64_t t0 = start_ns + k * period_ns;
    ts << KittiStamp(t0) << "\n";
    te << KittiStamp(t0 + period_ns) << "\n";
    tm << KittiStamp(t0 + period_ns / 2) << "\n";
    char name[32];
    std::snprintf(name, sizeof(name), "%010d.bin", k);
    std::ofstream bin(raw / "velodyne_points" / "data" / name, std::ios::binary);
    const PointFieldDesc *fx = c.Field("x"), *fy = c.Field("y"), *fz = c.Field("z"),
                         *fi = c.Field("intensity");
    for (size_t p = 0; p < c.num_points(); ++p) {
      const float v[4] = {c.Get<float>(p, *fx), c.Get<float>(p, *fy), c.Get<float>(p, *fz),
                          fi ? c.Get<float>(p, *fi) : 0.0f};
      if (!std::isfinite(v[0])) continue;
      bin.write(reinterpret_cast<const char*>(v), sizeof(v));
    }
  }
  // OXTS: lat/lon by inverting the devkit's Mercator projection about the first fix.
  const double er = 6378137.0, lat0 = 49.0, lon0 = 8.4;
  const double scale = std::cos(lat0 * M_PI / 180.0);
  const double mx0 = scale * er * lon0 * M_PI / 180.0;
  const double my0 = scale * er * std::log(std::tan((90.0 + lat0) * M_PI / 360.0));
  const Eigen::Vector3d p0 = world.trajectory.Pose(0.0).translation();
  std::ofstream ot(raw / "oxts" / "timestamps.txt");
  for (size_t i = 0; i < imu.size(); ++i) {
    const Eigen::Isometry3d T = world.trajectory.Pose(imu[i].t);
    const Eigen::Vector3d d = T.translation() - p0;
    const double lon = (mx0 + d.x()) * 180.0 / (M_PI * er * scale);
    const double lat = 360.0 / M_PI * std::atan(std::exp((my0 + d.y()) / (scale * er))) - 90.0;
    const Eigen::Matrix3d& R = T.linear();
    double v[30] = {0};
    v[0] = lat;
    v[1] = lon;
    v[2] = T.translation().z();
    v[3] = std::atan2(R(2, 1), R(2, 2));
    v[4] = -std::asin(std::clamp(R(2, 0), -1.0, 1.0));
    v[5] = std::atan2(R(1, 0), R(0, 0));
    for (int a = 0; a < 3; ++a) {
      v[11 + a] = imu[i].accel[a];
      v[17 + a] = imu[i].gyro[a];
    }
    char name[32];
    std::snprintf(name, sizeof(name), "%010zu.txt", i);
    std::ofstream f(raw / "oxts" / "data" / name);
    f << std::setprecision(15);
    for (int k = 0; k < 30; ++k) f << v[k] << (k < 29 ? " " : "\n");
    ot << KittiStamp(start_ns + static_cast<int64_t>(std::llround(imu[i].t * 1e9))) << "\n";
  }
  const Eigen::Isometry3d T_velo_imu = so.T_imu_lidar.inverse();
  std::ofstream cal(date_dir / "calib_imu_to_velo.txt");
  cal << std::setprecision(15) << "calib_time: simulated\nR:";
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) cal << " " << T_velo_imu.linear()(r, c);
  cal << "\nT: " << T_velo_imu.translation().x() << " " << T_velo_imu.translation().y() << " "
      << T_velo_imu.translation().z() << "\n";
}

TEST(MovingStartKitti, ImportedDriveRunsThroughTheOfflineLoop) {
  const double duration = 8.0;
  const fs::path date_dir = fs::path(PPF_TEST_WORKDIR) / "kitti" / "2011_09_26";
  const fs::path raw = date_dir / "2011_09_26_drive_0001_extract";
  const fs::path bag = fs::path(PPF_TEST_WORKDIR) / "kitti" / "bag";
  fs::remove_all(date_dir.parent_path());
  WriteKittiDrive(date_dir, raw, duration);
  const std::string import_exe =
      (fs::path(PPF_SIM_EXE).parent_path() / "ppf_import_kitti").string();
  const std::string cmd = import_exe + " --raw '" + raw.string() + "' --out '" + bag.string() +
                          "' > '" + bag.string() + ".log' 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "see " << bag.string() << ".log";
  ASSERT_TRUE(fs::exists(bag / "calibration.yaml"));
  fs::remove_all(date_dir);  // the raw drive (HDL-64 .bin files) is not needed past the import

  for (const ppf::Mode mode : {ppf::Mode::kKnn, ppf::Mode::kPpf}) {
    SCOPED_TRACE(mode == ppf::Mode::kKnn ? "knn" : "ppf");
    ppf::Config config;
    ASSERT_TRUE(ppf::tools::test::LoadPresetAndCalibration("hdl64", bag.string(), &config));
    config.mode = mode;
    const auto run = ppf::tools::RunOffline(bag.string(), config);
    ASSERT_FALSE(run.results.empty());
    ASSERT_FALSE(run.lidar_only);
    double first_pose = -1.0;
    size_t after_first = 0, valid_after_first = 0;
    for (const auto& r : run.results) {
      EXPECT_NE(r.status, ppf::Status::kReset) << r.reason;
      if (r.pose_valid && first_pose < 0) first_pose = r.stamp_s;
      if (first_pose >= 0) {
        ++after_first;
        valid_after_first += r.pose_valid;
      }
    }
    ASSERT_GE(first_pose, 0.0) << "no odometry: " << run.results.back().reason;
    EXPECT_LE(first_pose - run.results.front().scan_begin_s, 3.0);
    EXPECT_EQ(valid_after_first, after_first);

    ppf::Trajectory gt;
    std::string error;
    ASSERT_TRUE(ppf::ReadTum((bag / "groundtruth.tum").string(), &gt, &error)) << error;
    ppf::EvalOptions eval;
    eval.align = ppf::Alignment::kSE3;
    const auto ape = ppf::ComputeApe(gt, run.trajectory, eval);
    ASSERT_TRUE(ape.ok) << ape.error;
    eval.align = ppf::Alignment::kPosYaw;
    const auto ape_posyaw = ppf::ComputeApe(gt, run.trajectory, eval);
    ASSERT_TRUE(ape_posyaw.ok) << ape_posyaw.error;
    EXPECT_EQ(ape_posyaw.matched, valid_after_first);
    const double path = ppf::PathLength(run.trajectory);
    const double percent = 100.0 * ape_posyaw.stats.rmse / std::max(path, 1e-9);
    std::cout << "[ KITTI ] " << (mode == ppf::Mode::kKnn ? "knn" : "ppf") << ": first odometry "
              << first_pose - run.results.front().scan_begin_s << " s; APE SE(3) " << ape.stats.rmse
              << " m, position+yaw " << ape_posyaw.stats.rmse << " m over " << path << " m ("
              << percent << " %); tilt median " << ape_posyaw.gravity.tilt.median << " max "
              << ape_posyaw.gravity.tilt.max << " deg\n";
    EXPECT_LE(percent, 0.5);
  }
}

}  // namespace
