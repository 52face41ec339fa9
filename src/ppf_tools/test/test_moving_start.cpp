// Issue 15, moving start: sequences whose first scan and IMU sample are already in motion
// (ppf_sim --moving-start) must give odometry within 3 s of the first scan, with gravity right
// from the start: position+yaw-aligned APE (a tilted world shows as error there) within the
// static-start bound of the accuracy study, 0.5 % of the path, over the whole run. Before the
// moving-start initialization the IMU never showed rest and no scan got a pose.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "ppf_core/config.hpp"
#include "ppf_tools/offline_runner.hpp"
#include "ppf_tools/study.hpp"
#include "ppf_trajectory/evaluation.hpp"

#ifndef PPF_SIM_EXE
#define PPF_SIM_EXE "ppf_sim"
#endif
#ifndef PPF_CONFIG_DIR
#define PPF_CONFIG_DIR "config"
#endif

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

std::string Generate(const Case& c) {
  std::string n = c.sim_args + "_" + std::to_string(static_cast<int>(c.duration));
  for (char& ch : n) {
    if (ch == ' ' || ch == '-') ch = '_';
  }
  const fs::path dir = fs::path(PPF_TEST_WORKDIR) / n;
  const bool ok = ppf::tools::GenerateSequenceOnce(dir.string(), [&](const std::string& out) {
    std::ostringstream cmd;
    cmd << PPF_SIM_EXE << " " << c.sim_args << " --moving-start --duration " << c.duration
        << " --seed 1 --storage mcap --out '" << out << "' > '" << dir.string() << "." << ::getpid()
        << ".log' 2>&1";
    return std::system(cmd.str().c_str()) == 0;
  });
  EXPECT_TRUE(ok) << "ppf_sim failed, see " << dir.string() << ".<pid>.log";
  return dir.string();
}

class MovingStart : public ::testing::TestWithParam<Case> {};

TEST_P(MovingStart, OdometryWithin3sAndGravityRightFromTheStart) {
  const Case& c = GetParam();
  const std::string bag = Generate(c);
  ASSERT_TRUE(fs::exists(fs::path(bag) / "groundtruth.tum"));

  ppf::Config config;
  const auto report =
      ppf::LoadConfigYaml(std::string(PPF_CONFIG_DIR) + "/" + c.lidar + ".yaml", &config);
  ASSERT_TRUE(report.ok) << report.error;
  const auto calib = ppf::LoadConfigYaml(bag + "/calibration.yaml", &config);
  ASSERT_TRUE(calib.ok) << calib.error;
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

}  // namespace
